//! The pseudo-array: the sheet divided in software into a grid of virtual units, and the units
//! grouped into areas of equal sensitivity by the symmetry of the sensor.
//!
//! An EIT image is least sensitive far from the electrodes, so one force curve cannot serve the
//! whole sheet. The paper (§2.1.2, Figure 4a) answers with a pseudo-array: "a whole piece of the
//! tactile sensor is divided into a 5 × 5 array virtually", and "taking into account the symmetry
//! of the sensor, the sensing area is further divided into six areas". A touch belongs to the
//! unit holding its centre of gravity; the unit's area selects the fitted curve
//! σ(F) = a·e^(−F/b) + c (eq 4, Table 2) that turns the image's peak into a force (§3.3).
//!
//! Here the grid covers the outline's bounding box and the areas are found, not drawn: they are
//! the orbits of the units under the symmetries of the sensor, i.e. the elements of the dihedral
//! group D4 about the origin (rotations by 0°, 90°, 180°, 270°; reflections in x = 0, y = 0,
//! y = x, y = −x) that map (1) the box and the grid's unit centres, (2) the outline and (3) the
//! set of electrodes (centres and widths) onto themselves. A non-square box or an n × m grid with
//! n ≠ m keeps at most the four elements of D2; an irregular outline keeps only the identity, one
//! area per unit. On the paper's square with four electrodes a side, 5 × 5 gives its six areas.
//!
//! Numbering. Units count from 0 in code: unit u = row·nx + col, col 0 at the left (x_min) and
//! row 0 at the bottom (y_min), so unit 0 is the bottom-left unit (next to electrode 1 of the
//! paper's sensor). Areas count from 0 in code and are numbered as first met when the units are
//! scanned outward from the grid's centre in order of (min(|Δc|, |Δr|), max(|Δc|, |Δr|)), ties by
//! unit index, with the doubled offsets Δc = 2·col − (nx − 1), Δr = 2·row − (ny − 1). For the
//! paper's sensor this reproduces its numbering, area k here being the paper's area k + 1:
//! 0 the centre unit, 1 the four units beside it along the axes, 2 the four edge middles, 3 the
//! four diagonal neighbours of the centre, 4 the eight other edge units, 5 the four corners (the
//! paper's central areas 1, 2, 4 are 0, 1, 3 here). The paper, files and messages count both
//! units and areas from 1.
//!
//! ```
//! use eitskin::pseudo_array::PseudoArray;
//! use eitskin::SensorSpec;
//! let spec = SensorSpec::square_hydrogel(); // 200 mm square, four electrodes a side
//! let array = PseudoArray::of_sensor(&spec, [5, 5])?;
//! let unit = array.unit_at([0.0, -0.09]).ok_or("outside the sheet")?; // 10 mm above the bottom edge
//! assert_eq!((array.area_count(), unit, array.area_of(unit)), (6, 2, 2)); // the paper's area 3
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: calibrating (fitting a, b, c per area is the `calibration` module's job), nor for
//! finding touches in an image (that is [`crate::touch`]). The symmetries are those of the shape
//! and the electrodes only; they say nothing of the mesh, the protocol or the real sheet.

use thiserror::Error;

use crate::geometry::{arc_distance, Electrode, Outline};

/// Relative tolerance of the symmetry tests, as a fraction of the box size or the perimeter.
const TOLERANCE: f64 = 1e-9;

/// Boundary points sampled to test whether a symmetry maps the outline onto itself.
const BOUNDARY_SAMPLES: usize = 256;

/// The virtual units of the sheet and their areas of equal sensitivity.
#[derive(Debug, Clone, PartialEq)]
pub struct PseudoArray {
    /// Units along x and along y, `[nx, ny]`.
    grid: [usize; 2],
    /// The sensing area's box `[[x_min, y_min], [x_max, y_max]]`, in m.
    bounds: [[f64; 2]; 2],
    /// The 0-based area of each unit, row-major from the bottom-left.
    areas: Vec<usize>,
    /// Number of areas; the areas are `0..area_count`.
    area_count: usize,
}

/// Most units a pseudo-array has along x or along y.
pub const MAX_UNITS_PER_SIDE: usize = 100;

/// What is wrong with a pseudo-array's grid, box or user-given area map (1-based numbers in
/// messages and fields).
#[derive(Debug, Error, PartialEq)]
pub enum PseudoArrayError {
    /// The spec's electrodes could not be placed on its outline.
    #[error("the sensor spec does not make a sensor")]
    Spec(#[from] crate::SpecError),
    /// The grid has no unit along x or along y, or more than [`MAX_UNITS_PER_SIDE`].
    #[error(
        "the pseudo-array grid is {nx} × {ny} units; it needs 1 to {MAX_UNITS_PER_SIDE} units each way (the paper's is 5 × 5)"
    )]
    EmptyGrid {
        /// Units along x.
        nx: usize,
        /// Units along y.
        ny: usize,
    },
    /// The box is not finite or has no extent, in m.
    #[error("the sensing area's box runs from {min:?} to {max:?} m; it must be finite with max > min along x and y")]
    BadBounds {
        /// Corner `[x_min, y_min]`, in m.
        min: [f64; 2],
        /// Corner `[x_max, y_max]`, in m.
        max: [f64; 2],
    },
    /// The area map does not give one area per unit.
    #[error("the area map has {got} entries but the {nx} × {ny} grid has {expected} units; give one area per unit, row by row from the bottom-left")]
    WrongLength {
        /// Units along x.
        nx: usize,
        /// Units along y.
        ny: usize,
        /// Units in the grid, nx·ny.
        expected: usize,
        /// Entries given.
        got: usize,
    },
    /// An area number below the largest has no unit.
    #[error("area {missing} has no unit but area {largest} does; number the areas 1 to {largest} without gaps")]
    MissingArea {
        /// 1-based area with no unit.
        missing: usize,
        /// 1-based largest area given.
        largest: usize,
    },
}

impl PseudoArray {
    /// The paper's division of `spec`'s sheet: `grid` units over its outline's box, grouped by
    /// the symmetries of its outline and electrodes ([`PseudoArray::by_symmetry`]).
    pub fn of_sensor(spec: &crate::SensorSpec, grid: [usize; 2]) -> Result<PseudoArray, PseudoArrayError> {
        PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions()?, grid)
    }

    /// Units over `outline`'s bounding box (m) grouped by the symmetries of outline and electrodes.
    ///
    /// `grid` is `[nx, ny]`, units along x and along y; `electrodes` are arc-length intervals of
    /// `outline`'s boundary, as from [`crate::SensorSpec::electrode_positions`].
    pub fn by_symmetry(
        outline: &Outline,
        electrodes: &[Electrode],
        grid: [usize; 2],
    ) -> Result<PseudoArray, PseudoArrayError> {
        let blank = PseudoArray::blank(outline.bounds(), grid)?;
        let permutations: Vec<Vec<usize>> =
            symmetries(&blank, outline, electrodes).into_iter().map(|(_, permutation)| permutation).collect();
        Ok(blank.with_orbits(&permutations))
    }

    /// One area per unit (no symmetry used), over the box `bounds` in m, numbered in scan order.
    pub fn one_area_per_unit(bounds: [[f64; 2]; 2], grid: [usize; 2]) -> Result<PseudoArray, PseudoArrayError> {
        Ok(PseudoArray::blank(bounds, grid)?.with_orbits(&[]))
    }

    /// A user's map over the box `bounds` in m: the area (0-based) of each unit, row-major from
    /// the bottom-left; the areas used must be `0..k` without gaps.
    pub fn with_areas(
        bounds: [[f64; 2]; 2],
        grid: [usize; 2],
        areas: Vec<usize>,
    ) -> Result<PseudoArray, PseudoArrayError> {
        let blank = PseudoArray::blank(bounds, grid)?;
        let [nx, ny] = grid;
        if areas.len() != blank.unit_count() {
            return Err(PseudoArrayError::WrongLength { nx, ny, expected: blank.unit_count(), got: areas.len() });
        }
        let area_count = areas.iter().max().map_or(0, |&largest| largest + 1);
        let mut used = vec![false; area_count];
        for &area in &areas {
            used[area] = true;
        }
        if let Some(missing) = used.iter().position(|&u| !u) {
            return Err(PseudoArrayError::MissingArea { missing: missing + 1, largest: area_count });
        }
        Ok(PseudoArray { areas, area_count, ..blank })
    }

    /// Units along x and along y, `[nx, ny]`.
    pub fn grid(&self) -> [usize; 2] {
        self.grid
    }

    /// The sensing area's box `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub fn bounds(&self) -> [[f64; 2]; 2] {
        self.bounds
    }

    /// Number of units, nx·ny.
    pub fn unit_count(&self) -> usize {
        self.grid[0] * self.grid[1]
    }

    /// Number of areas; areas are indexed `0..area_count()`.
    pub fn area_count(&self) -> usize {
        self.area_count
    }

    /// The unit holding point `p` (m), `None` outside the box (points on the far edges belong to
    /// the last unit).
    pub fn unit_at(&self, p: [f64; 2]) -> Option<usize> {
        let col = cell(p[0], self.bounds[0][0], self.bounds[1][0], self.grid[0])?;
        let row = cell(p[1], self.bounds[0][1], self.bounds[1][1], self.grid[1])?;
        Some(row * self.grid[0] + col)
    }

    /// The 0-based area of `unit` (0-based).
    #[track_caller]
    pub fn area_of(&self, unit: usize) -> usize {
        self.check_unit(unit);
        self.areas[unit]
    }

    /// Centre of a unit, in m.
    #[track_caller]
    pub fn unit_centre(&self, unit: usize) -> [f64; 2] {
        let [[x_min, y_min], [x_max, y_max]] = self.unit_bounds(unit);
        [0.5 * (x_min + x_max), 0.5 * (y_min + y_max)]
    }

    /// The box of a unit `[[x_min, y_min], [x_max, y_max]]`, in m.
    #[track_caller]
    pub fn unit_bounds(&self, unit: usize) -> [[f64; 2]; 2] {
        self.check_unit(unit);
        let [nx, ny] = self.grid;
        let [[x_min, y_min], [x_max, y_max]] = self.bounds;
        let (col, row) = (unit % nx, unit / nx);
        [
            [edge(col, nx, x_min, x_max), edge(row, ny, y_min, y_max)],
            [edge(col + 1, nx, x_min, x_max), edge(row + 1, ny, y_min, y_max)],
        ]
    }

    /// The units (0-based) of an area (0-based), in unit order.
    pub fn units_in_area(&self, area: usize) -> Vec<usize> {
        (0..self.unit_count()).filter(|&u| self.areas[u] == area).collect()
    }

    /// A checked grid and box with no areas yet.
    fn blank(bounds: [[f64; 2]; 2], grid: [usize; 2]) -> Result<PseudoArray, PseudoArrayError> {
        let [nx, ny] = grid;
        if nx == 0 || ny == 0 || nx > MAX_UNITS_PER_SIDE || ny > MAX_UNITS_PER_SIDE {
            return Err(PseudoArrayError::EmptyGrid { nx, ny });
        }
        let [min, max] = bounds;
        let good = (0..2).all(|k| min[k].is_finite() && max[k].is_finite() && max[k] > min[k]);
        if !good {
            return Err(PseudoArrayError::BadBounds { min, max });
        }
        Ok(PseudoArray { grid, bounds, areas: Vec::new(), area_count: 0 })
    }

    /// This grid with its units grouped into the orbits of `permutations`, numbered in scan order.
    fn with_orbits(self, permutations: &[Vec<usize>]) -> PseudoArray {
        const UNSET: usize = usize::MAX;
        let mut areas = vec![UNSET; self.unit_count()];
        let mut area_count = 0;
        let mut stack = Vec::new();
        for unit in scan_order(self.grid) {
            if areas[unit] != UNSET {
                continue;
            }
            areas[unit] = area_count;
            stack.push(unit);
            while let Some(u) = stack.pop() {
                for permutation in permutations {
                    let image = permutation[u];
                    if areas[image] == UNSET {
                        areas[image] = area_count;
                        stack.push(image);
                    }
                }
            }
            area_count += 1;
        }
        PseudoArray { areas, area_count, ..self }
    }

    #[track_caller]
    fn check_unit(&self, unit: usize) {
        assert!(
            unit < self.unit_count(),
            "unit {unit} (0-based) is outside the {} units of the grid",
            self.unit_count()
        );
    }
}

/// One element of D4 about the origin: the orthogonal matrix acting on `[x, y]`, row-major.
#[derive(Debug, Clone, Copy)]
struct Symmetry([[f64; 2]; 2]);

impl Symmetry {
    /// The image of `p` (m).
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let m = self.0;
        [m[0][0] * p[0] + m[0][1] * p[1], m[1][0] * p[0] + m[1][1] * p[1]]
    }
}

/// The eight candidates: the dihedral group D4 about the origin.
const D4: [Symmetry; 8] = [
    Symmetry([[1.0, 0.0], [0.0, 1.0]]),   // identity
    Symmetry([[0.0, -1.0], [1.0, 0.0]]),  // rotation by 90°
    Symmetry([[-1.0, 0.0], [0.0, -1.0]]), // rotation by 180°
    Symmetry([[0.0, 1.0], [-1.0, 0.0]]),  // rotation by 270°
    Symmetry([[-1.0, 0.0], [0.0, 1.0]]),  // reflection in x = 0
    Symmetry([[1.0, 0.0], [0.0, -1.0]]),  // reflection in y = 0
    Symmetry([[0.0, 1.0], [1.0, 0.0]]),   // reflection in y = x
    Symmetry([[0.0, -1.0], [-1.0, 0.0]]), // reflection in y = −x
];

/// The elements of D4 (as indices into [`D4`]) that map the grid, `outline` and `electrodes`
/// onto themselves, each with the permutation of units it makes.
fn symmetries(grid: &PseudoArray, outline: &Outline, electrodes: &[Electrode]) -> Vec<(usize, Vec<usize>)> {
    (0..D4.len())
        .filter(|&k| {
            maps_outline_onto_itself(outline, &D4[k]) && maps_electrodes_onto_themselves(outline, electrodes, &D4[k])
        })
        .filter_map(|k| unit_permutation(grid, &D4[k]).map(|permutation| (k, permutation)))
        .collect()
}

/// Where `g` sends each unit, if it maps the box onto itself and unit centres onto unit centres.
fn unit_permutation(grid: &PseudoArray, g: &Symmetry) -> Option<Vec<usize>> {
    let [lo, hi] = grid.bounds;
    let tol = TOLERANCE * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let corners = [g.apply(lo), g.apply(hi)];
    for k in 0..2 {
        let (image_lo, image_hi) = (corners[0][k].min(corners[1][k]), corners[0][k].max(corners[1][k]));
        if (image_lo - lo[k]).abs() > tol || (image_hi - hi[k]).abs() > tol {
            return None;
        }
    }
    let mut hit = vec![false; grid.unit_count()];
    let mut permutation = Vec::with_capacity(grid.unit_count());
    for unit in 0..grid.unit_count() {
        let image = g.apply(grid.unit_centre(unit));
        let target = grid.unit_at(image)?;
        let centre = grid.unit_centre(target);
        if hit[target] || (image[0] - centre[0]).hypot(image[1] - centre[1]) > tol {
            return None;
        }
        hit[target] = true;
        permutation.push(target);
    }
    Some(permutation)
}

/// Whether `g` maps the boundary onto itself, tested on the corners and evenly spaced points.
///
/// `g` is an isometry, so an image of the closed boundary that lies on the boundary is all of it.
fn maps_outline_onto_itself(outline: &Outline, g: &Symmetry) -> bool {
    let perimeter = outline.perimeter();
    let tol = TOLERANCE * perimeter;
    let step = perimeter / BOUNDARY_SAMPLES as f64;
    (0..BOUNDARY_SAMPLES)
        .map(|k| outline.point_at(k as f64 * step))
        .chain(outline.corners())
        .all(|p| outline.locate(g.apply(p)).1 <= tol)
}

/// Whether `g` maps each electrode's centre onto a distinct electrode's centre of the same width.
fn maps_electrodes_onto_themselves(outline: &Outline, electrodes: &[Electrode], g: &Symmetry) -> bool {
    let perimeter = outline.perimeter();
    let tol = TOLERANCE * perimeter;
    let mut hit = vec![false; electrodes.len()];
    for electrode in electrodes {
        let (s, distance) = outline.locate(g.apply(outline.point_at(electrode.centre)));
        if distance > tol {
            return false;
        }
        let target = (0..electrodes.len()).find(|&j| {
            !hit[j]
                && arc_distance(s, electrodes[j].centre, perimeter) <= tol
                && (electrodes[j].width - electrode.width).abs() <= tol
        });
        match target {
            Some(j) => hit[j] = true,
            None => return false,
        }
    }
    true
}

/// The units ordered outward from the grid's centre: by (min(|Δc|, |Δr|), max(|Δc|, |Δr|)) of
/// the doubled offsets, then by unit index.
fn scan_order(grid: [usize; 2]) -> Vec<usize> {
    let [nx, ny] = grid;
    let offset = |i: usize, n: usize| (2 * i as i64 - (n as i64 - 1)).unsigned_abs();
    let mut order: Vec<usize> = (0..nx * ny).collect();
    order.sort_by_key(|&u| {
        let (dc, dr) = (offset(u % nx, nx), offset(u / nx, ny));
        (dc.min(dr), dc.max(dr), u)
    });
    order
}

/// The cell of `n` equal cells over `[lo, hi]` holding `v`; `hi` belongs to the last cell.
fn cell(v: f64, lo: f64, hi: f64, n: usize) -> Option<usize> {
    if !(lo..=hi).contains(&v) {
        return None;
    }
    Some((((v - lo) / (hi - lo) * n as f64).floor() as usize).min(n - 1))
}

/// Coordinate of grid line `i` of `n` equal cells over `[lo, hi]`, in m; line `n` is `hi` exactly.
fn edge(i: usize, n: usize, lo: f64, hi: f64) -> f64 {
    if i == n {
        hi
    } else {
        lo + (hi - lo) * i as f64 / n as f64
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use super::*;
    use crate::spec::{ElectrodeSpec, Placement, SensorSpec};

    /// The elements of [`D4`], in its order.
    const NAMES: [&str; 8] = [
        "identity",
        "rotation by 90°",
        "rotation by 180°",
        "rotation by 270°",
        "reflection in x = 0",
        "reflection in y = 0",
        "reflection in y = x",
        "reflection in y = −x",
    ];

    fn paper_array(grid: [usize; 2]) -> PseudoArray {
        let spec = SensorSpec::square_hydrogel();
        PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions().unwrap(), grid).unwrap()
    }

    /// The names of the symmetries that hold for `outline` and `electrodes` on a 5 × 5 grid.
    fn symmetry_names(outline: &Outline, electrodes: &[Electrode]) -> Vec<&'static str> {
        let grid = PseudoArray::blank(outline.bounds(), [5, 5]).unwrap();
        symmetries(&grid, outline, electrodes).iter().map(|&(k, _)| NAMES[k]).collect()
    }

    /// A spec with `outline` and 10 mm electrodes centred at `positions` (m).
    fn explicit(outline: Outline, positions: Vec<[f64; 2]>) -> (Outline, Vec<Electrode>) {
        let spec = SensorSpec {
            outline,
            electrodes: ElectrodeSpec {
                count: positions.len(),
                placement: Placement::Explicit { positions },
                ..SensorSpec::square_hydrogel().electrodes
            },
            ..SensorSpec::square_hydrogel()
        };
        let electrodes = spec.electrode_positions().unwrap();
        (spec.outline, electrodes)
    }

    fn disk(start_angle_deg: f64) -> (Outline, Vec<Electrode>) {
        let spec = SensorSpec {
            outline: Outline::Circle { radius: 0.1 },
            electrodes: ElectrodeSpec {
                placement: Placement::Equal { start_angle_deg },
                ..SensorSpec::square_hydrogel().electrodes
            },
            ..SensorSpec::square_hydrogel()
        };
        let electrodes = spec.electrode_positions().unwrap();
        (spec.outline, electrodes)
    }

    fn sizes(array: &PseudoArray) -> Vec<usize> {
        (0..array.area_count()).map(|a| array.units_in_area(a).len()).collect()
    }

    #[test]
    fn paper_square_5x5_gives_the_papers_six_areas_in_its_order() {
        let array = paper_array([5, 5]);
        assert_eq!(array.area_count(), 6);
        assert_eq!(sizes(&array), [1, 4, 4, 4, 8, 4]);
        // Figure 4a, written out by hand, bottom row first; paper's area = value + 1.
        #[rustfmt::skip]
        let expected = [
            5, 4, 2, 4, 5,
            4, 3, 1, 3, 4,
            2, 1, 0, 1, 2,
            4, 3, 1, 3, 4,
            5, 4, 2, 4, 5,
        ];
        let got: Vec<usize> = (0..25).map(|u| array.area_of(u)).collect();
        assert_eq!(got, expected);
        for (unit, area) in [(12, 0), (0, 5), (2, 2), (7, 1), (6, 3), (1, 4)] {
            assert_eq!(array.area_of(unit), area, "unit {unit}");
        }
        // §3.3: the paper's central areas 1, 2, 4 (0, 1, 3 here) are off the border, its edge
        // areas 3, 5, 6 (2, 4, 5 here) on it.
        let on_border = |u: usize| [u % 5, u / 5].iter().any(|&i| i == 0 || i == 4);
        for area in 0..6 {
            let border = array.units_in_area(area).iter().all(|&u| on_border(u));
            let inner = array.units_in_area(area).iter().all(|&u| !on_border(u));
            assert!(if [0, 1, 3].contains(&area) { inner } else { border }, "area {area}");
        }
        // §3.3: the lower-left 3 × 3 units, where the fitting data were taken, meet every area.
        let lower_left: BTreeSet<usize> =
            (0..3).flat_map(|row| (0..3).map(move |col| row * 5 + col)).map(|u| array.area_of(u)).collect();
        assert_eq!(lower_left, (0..6).collect());
    }

    #[test]
    fn paper_square_3x3_has_three_areas_and_10x10_the_d4_orbit_count() {
        let array = paper_array([3, 3]);
        assert_eq!((array.area_count(), sizes(&array)), (3, vec![1, 4, 4]));
        // Under D4 a unit's orbit is fixed by the unordered pair {|Δc|, |Δr|} of its doubled
        // offsets from the centre. For 10 × 10 these take the 5 values 1, 3, 5, 7, 9, so there
        // are 5 pairs {a, a} and C(5, 2) = 10 pairs {a, b}, a ≠ b: 15 orbits.
        let array = paper_array([10, 10]);
        assert_eq!(array.area_count(), 15);
        let pair = |u: usize| {
            let (dc, dr) = ((2 * (u % 10) as i64 - 9).abs(), (2 * (u / 10) as i64 - 9).abs());
            (dc.min(dr), dc.max(dr))
        };
        for u in 0..100 {
            for v in 0..100 {
                assert_eq!(array.area_of(u) == array.area_of(v), pair(u) == pair(v), "units {u} and {v}");
            }
        }
    }

    #[test]
    fn irregular_pentagon_has_one_area_per_unit() {
        // Its box is centred on the origin and square, so the box and grid test keeps all of D4
        // and the outline test must reject all but the identity.
        let points = vec![[-0.08, -0.1], [0.1, -0.06], [0.07, 0.1], [-0.03, 0.08], [-0.1, 0.01]];
        let midpoints = (0..5).map(|k| {
            let (a, b) = (points[k], points[(k + 1) % 5]);
            [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]
        });
        let (outline, electrodes) = explicit(Outline::Polygon { points: points.clone() }, midpoints.collect());
        assert_eq!(outline.bounds(), [[-0.1, -0.1], [0.1, 0.1]]);
        let grid = PseudoArray::blank(outline.bounds(), [5, 5]).unwrap();
        assert!(D4.iter().all(|g| unit_permutation(&grid, g).is_some()));
        let kept: Vec<&str> =
            (0..8).filter(|&k| maps_outline_onto_itself(&outline, &D4[k])).map(|k| NAMES[k]).collect();
        assert_eq!(kept, ["identity"]);
        assert_eq!(symmetry_names(&outline, &electrodes), ["identity"]);
        let array = PseudoArray::by_symmetry(&outline, &electrodes, [5, 5]).unwrap();
        assert_eq!(array.area_count(), 25);
        assert_eq!(array, PseudoArray::one_area_per_unit(outline.bounds(), [5, 5]).unwrap());
    }

    #[test]
    fn square_without_top_electrodes_keeps_only_the_mirror_in_x_0() {
        // Four electrodes on the bottom, right and left sides, none on the top: only the
        // reflection in x = 0 (swapping left and right) holds. It pairs columns 0 ↔ 4 and
        // 1 ↔ 3 and fixes column 2, so each of the 5 rows has 3 areas: 15.
        let at = [-0.075, -0.025, 0.025, 0.075];
        let positions: Vec<[f64; 2]> = at
            .iter()
            .map(|&x| [x, -0.1])
            .chain(at.iter().map(|&y| [0.1, y]))
            .chain(at.iter().map(|&y| [-0.1, y]))
            .collect();
        let (outline, electrodes) = explicit(Outline::Rectangle { width: 0.2, height: 0.2 }, positions);
        assert_eq!(symmetry_names(&outline, &electrodes), ["identity", "reflection in x = 0"]);
        let array = PseudoArray::by_symmetry(&outline, &electrodes, [5, 5]).unwrap();
        assert_eq!(array.area_count(), 15);
        assert_eq!(array.area_of(12), 0);
        assert_eq!(array.area_of(0), array.area_of(4));
        assert_ne!(array.area_of(0), array.area_of(20));
    }

    #[test]
    fn square_with_electrodes_shifted_counter_clockwise_keeps_only_the_rotations() {
        // Moving every electrode 5 mm counter-clockwise keeps the pattern under the rotations
        // but a reflection turns the shift clockwise. C4 fixes the centre unit and moves the other
        // 24 units in orbits of 4: 1 + 6 = 7 areas.
        let spec = SensorSpec::square_hydrogel();
        let shifted: Vec<Electrode> =
            spec.electrode_positions().unwrap().iter().map(|e| Electrode { centre: e.centre + 0.005, ..*e }).collect();
        let names = symmetry_names(&spec.outline, &shifted);
        assert_eq!(names, ["identity", "rotation by 90°", "rotation by 180°", "rotation by 270°"]);
        let array = PseudoArray::by_symmetry(&spec.outline, &shifted, [5, 5]).unwrap();
        assert_eq!((array.area_count(), sizes(&array)), (7, vec![1, 4, 4, 4, 4, 4, 4]));
    }

    #[test]
    fn non_square_box_or_grid_keeps_only_d2() {
        // A 300 × 200 mm rectangle with four electrodes a side: the reflections in the axes and
        // the half turn. D2 orbits are fixed by (|Δc|, |Δr|), each in {0, 2, 4}: 9 areas.
        let spec =
            SensorSpec { outline: Outline::Rectangle { width: 0.3, height: 0.2 }, ..SensorSpec::square_hydrogel() };
        let electrodes = spec.electrode_positions().unwrap();
        let names = symmetry_names(&spec.outline, &electrodes);
        assert_eq!(names, ["identity", "rotation by 180°", "reflection in x = 0", "reflection in y = 0"]);
        assert_eq!(PseudoArray::by_symmetry(&spec.outline, &electrodes, [5, 5]).unwrap().area_count(), 9);
        // The paper's square on 5 × 3 units: |Δc| ∈ {0, 2, 4}, |Δr| ∈ {0, 2}: 6 areas.
        let array = paper_array([5, 3]);
        assert_eq!((array.area_count(), sizes(&array)), (6, vec![1, 2, 2, 2, 4, 4]));
    }

    #[test]
    fn disk_with_sixteen_electrodes_from_0_degrees_has_all_of_d4() {
        // Electrodes at k·22.5°: every rotation by a multiple of 90° and every reflection in an
        // axis at a multiple of 45° maps the set onto itself.
        let (outline, electrodes) = disk(0.0);
        assert_eq!(symmetry_names(&outline, &electrodes).len(), 8);
        let array = PseudoArray::by_symmetry(&outline, &electrodes, [5, 5]).unwrap();
        assert_eq!((array.area_count(), sizes(&array)), (6, vec![1, 4, 4, 4, 8, 4]));
    }

    #[test]
    fn disk_with_sixteen_electrodes_from_10_degrees_keeps_only_the_rotations() {
        // Electrodes at 10° + k·22.5°. A rotation by 90° = 4 · 22.5° maps the set onto itself.
        // A reflection in the axis at angle φ sends θ to 2φ − θ and needs 2φ − 20° to be a
        // multiple of 22.5°; for φ = 0°, 45°, 90°, 135° that is −20°, 70°, 160°, 250°: none.
        let (outline, electrodes) = disk(10.0);
        let names = symmetry_names(&outline, &electrodes);
        assert_eq!(names, ["identity", "rotation by 90°", "rotation by 180°", "rotation by 270°"]);
        assert_eq!(PseudoArray::by_symmetry(&outline, &electrodes, [5, 5]).unwrap().area_count(), 7);
    }

    #[test]
    fn one_area_per_unit_is_numbered_outward_from_the_centre() {
        let array = PseudoArray::one_area_per_unit([[-1.0, -1.0], [1.0, 1.0]], [3, 3]).unwrap();
        let got: Vec<usize> = (0..9).map(|u| array.area_of(u)).collect();
        // Centre first, then the edge middles (units 1, 3, 5, 7), then the corners (0, 2, 6, 8).
        assert_eq!(got, [5, 1, 6, 2, 0, 3, 7, 4, 8]);
    }

    #[test]
    fn unit_at_inverts_unit_centre_and_gives_the_far_edges_to_the_last_unit() {
        let array = paper_array([5, 4]);
        for unit in 0..array.unit_count() {
            let centre = array.unit_centre(unit);
            assert_eq!(array.unit_at(centre), Some(unit));
            let [lo, hi] = array.unit_bounds(unit);
            assert!(lo[0] < centre[0] && centre[0] < hi[0] && lo[1] < centre[1] && centre[1] < hi[1]);
        }
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-15 && (a[1] - b[1]).abs() < 1e-15;
        assert!(close(array.unit_centre(0), [-0.08, -0.075]));
        let [lo, hi] = array.unit_bounds(19);
        assert!(close(lo, [0.06, 0.05]) && hi == [0.1, 0.1], "{lo:?} {hi:?}");
        assert_eq!(array.unit_at([-0.1, -0.1]), Some(0));
        assert_eq!(array.unit_at([0.1, 0.1]), Some(19));
        assert_eq!(array.unit_at([0.1, -0.1]), Some(4));
        assert_eq!(array.unit_at([0.1 + 1e-9, 0.0]), None);
        assert_eq!(array.unit_at([0.0, -0.2]), None);
        assert_eq!(array.unit_at([f64::NAN, 0.0]), None);
    }

    #[test]
    fn with_areas_checks_the_map_and_names_what_is_wrong() {
        let bounds = [[-0.1, -0.1], [0.1, 0.1]];
        let paper = paper_array([5, 5]);
        let areas: Vec<usize> = (0..25).map(|u| paper.area_of(u)).collect();
        assert_eq!(PseudoArray::with_areas(bounds, [5, 5], areas.clone()), Ok(paper));

        let err = PseudoArray::with_areas(bounds, [5, 5], vec![0; 24]).unwrap_err();
        assert_eq!(err, PseudoArrayError::WrongLength { nx: 5, ny: 5, expected: 25, got: 24 });
        assert!(err.to_string().contains("24 entries but the 5 × 5 grid has 25 units"), "{err}");

        // Areas 0, 1, 3 used (1, 2, 4 in the message): the first gap is the paper's area 3.
        let gap: Vec<usize> = areas.iter().map(|&a| a.min(3)).map(|a| if a == 2 { 3 } else { a }).collect();
        let err = PseudoArray::with_areas(bounds, [5, 5], gap).unwrap_err();
        assert_eq!(err, PseudoArrayError::MissingArea { missing: 3, largest: 4 });
        assert!(err.to_string().starts_with("area 3 has no unit but area 4 does"), "{err}");

        let err = PseudoArray::with_areas(bounds, [0, 5], Vec::new()).unwrap_err();
        assert_eq!(err, PseudoArrayError::EmptyGrid { nx: 0, ny: 5 });
        // Too many units is refused before any is made.
        let err = PseudoArray::one_area_per_unit(bounds, [MAX_UNITS_PER_SIDE + 1, 100_000]).unwrap_err();
        assert_eq!(err, PseudoArrayError::EmptyGrid { nx: MAX_UNITS_PER_SIDE + 1, ny: 100_000 });
        let flat = [[-0.1, 0.1], [0.1, 0.1]];
        let err = PseudoArray::one_area_per_unit(flat, [5, 5]).unwrap_err();
        assert_eq!(err, PseudoArrayError::BadBounds { min: [-0.1, 0.1], max: [0.1, 0.1] });
    }
}
