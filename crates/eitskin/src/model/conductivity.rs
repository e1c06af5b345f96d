//! Conductivity per triangle, from a background and circular inclusions.
//!
//! A triangle cut by an inclusion's circle gets the area-weighted value
//! σ_e = (1 − f_e)·σ_e + f_e·σ_incl, with f_e the exact share of the triangle's area inside
//! the circle. Inclusions are applied in order, so a later one overrides an earlier one.
//!
//! [`check_inclusion`] refuses an inclusion that would change nothing on a mesh: its disc
//! covers no triangle's centroid (off the sheet, or smaller than the mesh's triangles).
//! Conductivities, a spec's and an inclusion's, lie in [[`MIN_CONDUCTIVITY`],
//! [`MAX_CONDUCTIVITY`]] S/m.

use thiserror::Error;

use crate::mesh::{Mesh, PointLocator};
use crate::spec::{LengthUnit, Quantity};

/// The least conductivity a spec or an inclusion takes, in S/m: a millionth of tap water's
/// order; below it the model's matrix loses its positive pivots to rounding.
pub const MIN_CONDUCTIVITY: f64 = 1e-6;

/// The largest conductivity a spec or an inclusion takes, in S/m: beyond a metal's order (a
/// tenth of copper's), far past any skin.
pub const MAX_CONDUCTIVITY: f64 = 1e6;

/// Whether `conductivity` (S/m) is a finite number in [[`MIN_CONDUCTIVITY`], [`MAX_CONDUCTIVITY`]].
pub fn conductivity_in_range(conductivity: f64) -> bool {
    (MIN_CONDUCTIVITY..=MAX_CONDUCTIVITY).contains(&conductivity)
}

/// Why an inclusion is refused on a mesh; lengths quoted in the `unit` the user gave them in.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum InclusionError {
    /// Its centre lies off the sheet, and its disc covers no triangle's centroid.
    #[error(
        "its centre ({}, {}) {unit} is off the sheet (x from {} to {} {unit}, y from {} to {} {unit}) and its disc covers no triangle of the mesh: give a centre on the sheet, in {unit} from the outline's origin",
        plain(*unit, centre[0]), plain(*unit, centre[1]), plain(*unit, bounds[0][0]), plain(*unit, bounds[1][0]),
        plain(*unit, bounds[0][1]), plain(*unit, bounds[1][1]), unit = unit.symbol()
    )]
    OffSheet {
        /// The centre given, in m.
        centre: [f64; 2],
        /// The mesh's bounding box, `[[x_min, y_min], [x_max, y_max]]`, in m.
        bounds: [[f64; 2]; 2],
        /// The unit the user gives lengths in, which the message quotes them in.
        unit: LengthUnit,
    },
    /// Its disc, on the sheet, is too small to cover any triangle's centroid.
    #[error(
        "its radius {} covers no triangle's centroid of this mesh of {triangles} triangles, so it would change nothing: give a radius of at least {}, or mesh with more triangles",
        unit.quote(*radius), Quantity::derived(smallest / unit.metres(), unit.symbol())
    )]
    TooSmall {
        /// The radius given, in m.
        radius: f64,
        /// The smallest radius that covers a centroid (the distance to the nearest), in m.
        smallest: f64,
        /// Triangles in the mesh.
        triangles: usize,
        /// The unit the user gives lengths in, which the message quotes them in.
        unit: LengthUnit,
    },
    /// Its conductivity is outside [[`MIN_CONDUCTIVITY`], [`MAX_CONDUCTIVITY`]].
    #[error("its conductivity {} is outside {CONDUCTIVITY_RANGE}", Quantity::written(*conductivity, "S/m"))]
    Conductivity {
        /// The conductivity given, in S/m.
        conductivity: f64,
    },
}

/// [`MIN_CONDUCTIVITY`] to [`MAX_CONDUCTIVITY`] as messages state the range.
pub const CONDUCTIVITY_RANGE: &str = "[1e-6, 1e6] S/m";

/// `metres` in `unit`, as written, without the unit's symbol.
fn plain(unit: LengthUnit, metres: f64) -> Quantity {
    Quantity::written(metres / unit.metres(), "")
}

/// Checks that `inclusion` changes `mesh`: its conductivity is in range and its disc covers
/// the centroid of at least one triangle; gives the number of triangles whose centroid it
/// covers. A disc that covers none is refused as off the sheet when its centre lies outside
/// the mesh, and as too small otherwise (with the smallest radius that would cover one);
/// `unit` is the unit the messages quote lengths in.
pub fn check_inclusion(mesh: &Mesh, inclusion: &Inclusion, unit: LengthUnit) -> Result<usize, InclusionError> {
    if !conductivity_in_range(inclusion.conductivity) {
        return Err(InclusionError::Conductivity { conductivity: inclusion.conductivity });
    }
    let distance = |t: usize| {
        let [x, y] = mesh.centroid(t);
        (x - inclusion.centre[0]).hypot(y - inclusion.centre[1])
    };
    let triangles = mesh.triangles().len();
    let covered = (0..triangles).filter(|&t| distance(t) <= inclusion.radius).count();
    if covered > 0 {
        return Ok(covered);
    }
    if PointLocator::new(mesh).locate(inclusion.centre).is_none() {
        return Err(InclusionError::OffSheet { centre: inclusion.centre, bounds: mesh.bounds(), unit });
    }
    let smallest = (0..triangles).map(distance).fold(f64::INFINITY, f64::min);
    Err(InclusionError::TooSmall { radius: inclusion.radius, smallest, triangles, unit })
}

/// A circular region of different conductivity: centre and radius in m, conductivity in S/m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inclusion {
    /// Centre `[x, y]`, in m.
    pub centre: [f64; 2],
    /// Radius, in m.
    pub radius: f64,
    /// Conductivity inside, in S/m.
    pub conductivity: f64,
}

/// One conductivity per triangle of `mesh` (S/m): `background` with `inclusions` over it.
pub fn with_inclusions(mesh: &Mesh, background: f64, inclusions: &[Inclusion]) -> Vec<f64> {
    (0..mesh.triangles().len()).map(|t| mixed(mesh.corners(t), mesh.area(t), background, inclusions)).collect()
}

/// The conductivity (S/m) of a triangle with `corners` and `area` (m²): `background` with each
/// of `inclusions` in turn mixed in by the share of the triangle it covers.
pub fn mixed(corners: [[f64; 2]; 3], area: f64, background: f64, inclusions: &[Inclusion]) -> f64 {
    let mut s = background;
    for inc in inclusions {
        // A triangle whose box lies clear of the circle keeps its value exactly (the exact area
        // would be zero up to rounding), and costs no arc tangents.
        if box_distance(inc.centre, corners) > inc.radius {
            continue;
        }
        // A triangle covered whole has a share of exactly 1 (the sectors' sum would give 1 up
        // to rounding), and costs no arc tangents either.
        let f = if covered_whole(inc.centre, inc.radius, corners) {
            1.0
        } else {
            (circle_triangle_area(inc.centre, inc.radius, corners) / area).clamp(0.0, 1.0)
        };
        if f > 0.0 {
            s = (1.0 - f) * s + f * inc.conductivity;
        }
    }
    s
}

/// Whether the disk (`centre`, `radius`, m) covers a triangle's `corners` whole: every corner
/// strictly inside its circle.
pub fn covered_whole(centre: [f64; 2], radius: f64, corners: [[f64; 2]; 3]) -> bool {
    let squared = radius * radius;
    corners.iter().all(|c| (c[0] - centre[0]).powi(2) + (c[1] - centre[1]).powi(2) < squared)
}

/// Distance from `p` to the bounding box of a triangle's `corners`, in m (0 inside it).
pub fn box_distance(p: [f64; 2], corners: [[f64; 2]; 3]) -> f64 {
    box_distance_squared(p, corners).sqrt()
}

/// [`box_distance`] squared, in m² (without the root, for a test against a radius).
pub fn box_distance_squared(p: [f64; 2], corners: [[f64; 2]; 3]) -> f64 {
    let [x_lo, y_lo, x_hi, y_hi] = triangle_box(corners);
    let (x, y) = ((x_lo - p[0]).max(p[0] - x_hi).max(0.0), (y_lo - p[1]).max(p[1] - y_hi).max(0.0));
    x * x + y * y
}

/// The bounding box of a triangle's `corners`: `[x_min, y_min, x_max, y_max]`, in m.
pub fn triangle_box(corners: [[f64; 2]; 3]) -> [f64; 4] {
    let (x, y) = (corners.map(|c| c[0]), corners.map(|c| c[1]));
    let (lo, hi) = (|v: [f64; 3]| v[0].min(v[1]).min(v[2]), |v: [f64; 3]| v[0].max(v[1]).max(v[2]));
    [lo(x), lo(y), hi(x), hi(y)]
}

/// Exact area of the intersection of the disk (`centre`, `radius`) with a counter-clockwise
/// triangle, in m²: the sum over the edges of the signed disk ∩ (centre, a, b) areas.
pub fn circle_triangle_area(centre: [f64; 2], radius: f64, corners: [[f64; 2]; 3]) -> f64 {
    let rel = corners.map(|p| [p[0] - centre[0], p[1] - centre[1]]);
    (0..3).map(|i| sector_triangle(rel[i], rel[(i + 1) % 3], radius, None)).sum()
}

/// [`circle_triangle_area`] (m²) with its derivatives along the centre's x and y and the
/// radius (m² per m), exact: moving the disk's boundary sweeps area only along the arcs of it
/// inside the triangle, so ∂A/∂centre = ∫ n ds and ∂A/∂r = ∫ ds over those arcs (n the
/// circle's outward normal), read off the same sectors as the area.
pub fn circle_triangle_area_gradient(centre: [f64; 2], radius: f64, corners: [[f64; 2]; 3]) -> (f64, [f64; 3]) {
    let rel = corners.map(|p| [p[0] - centre[0], p[1] - centre[1]]);
    let mut gradient = [0.0; 3];
    let area = (0..3).map(|i| sector_triangle(rel[i], rel[(i + 1) % 3], radius, Some(&mut gradient))).sum();
    (area, gradient)
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// Signed area of the disk of radius `r` at the origin intersected with triangle (0, a, b);
/// with `gradient`, adds to it the area's derivatives along the disk's centre (x, y) and `r`.
fn sector_triangle(a: [f64; 2], b: [f64; 2], r: f64, mut gradient: Option<&mut [f64; 3]>) -> f64 {
    // The arc at radius r from direction u to v (signed), its area and, if asked, its sweep.
    let mut sector = |u: [f64; 2], v: [f64; 2]| {
        let angle = cross(u, v).atan2(dot(u, v));
        if let Some(g) = gradient.as_deref_mut() {
            // Lengths on a sheet (m), far from overflow: no `hypot` needed.
            let (nu, nv) = (dot(u, u).sqrt(), dot(v, v).sqrt());
            if nu > 0.0 && nv > 0.0 {
                // ∫ (cos θ, sin θ) r dθ from θ_u to θ_v.
                g[0] += r * (v[1] / nv - u[1] / nu);
                g[1] += r * (u[0] / nu - v[0] / nv);
            }
            g[2] += r * angle;
        }
        0.5 * r * r * angle
    };
    let d = [b[0] - a[0], b[1] - a[1]];
    let qa = dot(d, d);
    if qa == 0.0 {
        return 0.0;
    }
    let qb = dot(a, d);
    let qc = dot(a, a) - r * r;
    let disc = qb * qb - qa * qc;
    if disc <= 0.0 {
        return sector(a, b);
    }
    let root = disc.sqrt();
    let (t1, t2) = ((-qb - root) / qa, (-qb + root) / qa);
    if t2 <= 0.0 || t1 >= 1.0 {
        return sector(a, b);
    }
    let at = |t: f64| [a[0] + t * d[0], a[1] + t * d[1]];
    let (p1, p2) = (at(t1.max(0.0)), at(t2.min(1.0)));
    let first = if t1 > 0.0 { sector(a, p1) } else { 0.0 };
    let last = if t2 < 1.0 { sector(p2, b) } else { 0.0 };
    first + 0.5 * cross(p1, p2) + last
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    const TRI: [[f64; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];

    /// An inclusion off the sheet, or smaller than the triangles, is refused, saying which and
    /// quoting the values in the user's unit; one that covers a centroid is not.
    #[test]
    fn an_inclusion_that_covers_no_triangle_is_refused() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 500;
        let mesh = spec.mesh().unwrap();
        let mm = LengthUnit::Millimetre;
        let inclusion = |x: f64, radius: f64| Inclusion { centre: [x, 0.0], radius, conductivity: 0.5 };
        assert!(check_inclusion(&mesh, &inclusion(0.0, 0.03), mm).unwrap() > 0);
        let err = check_inclusion(&mesh, &inclusion(5.0, 0.01), mm).unwrap_err();
        assert!(matches!(err, InclusionError::OffSheet { .. }), "{err}");
        assert!(
            err.to_string()
                .starts_with("its centre (5000, 0) mm is off the sheet (x from -100 to 100 mm, y from -100 to 100 mm)"),
            "{err}"
        );
        let err = check_inclusion(&mesh, &inclusion(0.0, 1e-12), mm).unwrap_err();
        let InclusionError::TooSmall { smallest, triangles, .. } = err else { panic!("{err}") };
        assert!(smallest > 1e-12 && smallest < 0.02 && triangles == mesh.triangles().len(), "{err}");
        assert!(err.to_string().starts_with("its radius 1e-9 mm covers no triangle's centroid"), "{err}");
        // The smallest radius it names does cover one.
        assert!(check_inclusion(&mesh, &inclusion(0.0, smallest), mm).is_ok());
        // Off the sheet but reaching over its edge: it covers triangles, so it stands.
        assert!(check_inclusion(&mesh, &inclusion(0.11, 0.05), mm).is_ok());
        let wrong = Inclusion { conductivity: 1e-300, ..inclusion(0.0, 0.03) };
        assert_eq!(
            check_inclusion(&mesh, &wrong, mm).unwrap_err().to_string(),
            "its conductivity 1e-300 S/m is outside [1e-6, 1e6] S/m"
        );
    }

    #[test]
    fn whole_triangle_and_whole_disk() {
        assert!((circle_triangle_area([0.2, 0.2], 5.0, TRI) - 0.5).abs() < 1e-14);
        assert!((circle_triangle_area([0.25, 0.25], 0.1, TRI) - PI * 0.01).abs() < 1e-14);
        assert_eq!(circle_triangle_area([3.0, 3.0], 0.5, TRI), 0.0);
    }

    #[test]
    fn quarter_disk_at_the_right_angle() {
        assert!((circle_triangle_area([0.0, 0.0], 0.5, TRI) - PI * 0.25 / 4.0).abs() < 1e-14);
    }

    #[test]
    fn partial_overlap_matches_a_fine_sample_count() {
        let (c, r) = ([0.6, 0.3], 0.35);
        let n = 2000;
        let mut inside = 0usize;
        for i in 0..n {
            for j in 0..n {
                let p = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                if p[0] + p[1] <= 1.0 && (p[0] - c[0]).hypot(p[1] - c[1]) < r {
                    inside += 1;
                }
            }
        }
        let sampled = inside as f64 / (n * n) as f64;
        let exact = circle_triangle_area(c, r, TRI);
        assert!((exact - sampled).abs() < 2e-4, "exact {exact}, sampled {sampled}");
    }

    /// The gradient against central differences of the area itself, for a disk across one
    /// corner, across an edge, over a whole corner-free triangle's side, inside and outside;
    /// and against two facts: a half-plane's chord (2r along x) and a disk inside (0, 0, 2πr).
    #[test]
    fn the_overlaps_gradient_is_its_central_difference() {
        let cases = [([0.0, 0.0], 0.5), ([0.6, 0.3], 0.35), ([0.5, -0.1], 0.3), ([0.3, 0.3], 0.9), ([2.0, 2.0], 0.3)];
        let h = 1e-6;
        for (c, r) in cases {
            let (area, g) = circle_triangle_area_gradient(c, r, TRI);
            assert_eq!(area, circle_triangle_area(c, r, TRI));
            let by_x = (circle_triangle_area([c[0] + h, c[1]], r, TRI)
                - circle_triangle_area([c[0] - h, c[1]], r, TRI))
                / (2.0 * h);
            let by_y = (circle_triangle_area([c[0], c[1] + h], r, TRI)
                - circle_triangle_area([c[0], c[1] - h], r, TRI))
                / (2.0 * h);
            let by_r = (circle_triangle_area(c, r + h, TRI) - circle_triangle_area(c, r - h, TRI)) / (2.0 * h);
            for (analytic, difference) in g.iter().zip([by_x, by_y, by_r]) {
                assert!((analytic - difference).abs() < 1e-7, "{c:?} {r}: {g:?} vs {:?}", [by_x, by_y, by_r]);
            }
        }
        let big = [[0.0, -10.0], [10.0, 0.0], [0.0, 10.0]];
        let (_, g) = circle_triangle_area_gradient([0.0, 0.0], 0.5, big);
        assert!((g[0] - 1.0).abs() < 1e-12 && g[1].abs() < 1e-12 && (g[2] - PI * 0.5).abs() < 1e-12, "{g:?}");
        let (_, g) = circle_triangle_area_gradient([0.25, 0.25], 0.1, TRI);
        assert!(g[0].abs() < 1e-15 && g[1].abs() < 1e-15 && (g[2] - 2.0 * PI * 0.1).abs() < 1e-14, "{g:?}");
    }
}
