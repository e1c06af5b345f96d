//! Mesh generation: constrained Delaunay triangulation of the outline with Ruppert
//! refinement (spade), graded toward the electrode edges where the current crowds.
//!
//! The boundary is sampled with a spacing h(s) = min(h₀, g·h₀ + γ·d(s)), where h₀ is the
//! interior element size, g the grading ratio, d(s) the arc distance to the nearest electrode
//! end and γ = 0.25 the growth rate; Ruppert refinement with a minimum angle then carries the
//! fine boundary spacing smoothly into the interior.

use std::collections::HashSet;

use spade::{AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation};

use super::{Mesh, MeshError};
use crate::geometry::{arc_distance, Electrode, Outline};

/// Growth rate γ of the boundary spacing away from electrode ends (dimensionless).
const GROWTH: f64 = 0.25;

/// How finely to mesh; a plain struct with public fields and the paper sensor's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshParams {
    /// Target number of triangles (met within a few per cent), unless `max_element_size` is set.
    pub triangles: usize,
    /// Interior element size (edge length) in m; overrides `triangles` when set.
    pub max_element_size: Option<f64>,
    /// Element size at electrode edges as a fraction of the interior size, in (0, 1]; 1 is uniform.
    pub grading: f64,
    /// Minimum interior angle the refinement keeps, in degrees (at most about 30).
    pub min_angle_deg: f64,
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams { triangles: 4000, max_element_size: None, grading: 0.2, min_angle_deg: 30.0 }
    }
}

impl Mesh {
    /// Meshes `outline` with `electrodes` (arc-length intervals; width 0 for point electrodes)
    /// so that every electrode end is a node and each electrode's boundary nodes are listed.
    pub fn generate(outline: &Outline, electrodes: &[Electrode], params: &MeshParams) -> Result<Mesh, MeshError> {
        let equilateral = |h: f64| 3f64.sqrt() / 4.0 * h * h;
        if let Some(h) = params.max_element_size {
            return build(outline, electrodes, params, h);
        }
        let target = params.triangles.max(2) as f64;
        let mut h0 = (outline.area() / target / equilateral(1.0)).sqrt();
        let mut mesh = build(outline, electrodes, params, h0)?;
        // The count follows h₀⁻² closely; two corrections land within a few per cent.
        for _ in 0..3 {
            let ratio = mesh.triangles().len() as f64 / target;
            if (ratio - 1.0).abs() < 0.03 {
                break;
            }
            h0 *= ratio.sqrt();
            mesh = build(outline, electrodes, params, h0)?;
        }
        Ok(mesh)
    }
}

/// Spade's reason for refusing a boundary point, in words.
fn insertion_problem(error: spade::InsertionError) -> &'static str {
    match error {
        spade::InsertionError::TooSmall => "a boundary coordinate is nearer zero than 1.8e-43 m without being zero",
        spade::InsertionError::TooLarge => "a boundary coordinate is larger than 3.2e60 m",
        spade::InsertionError::NAN => "a boundary coordinate is not a number",
    }
}

fn build(outline: &Outline, electrodes: &[Electrode], params: &MeshParams, h0: f64) -> Result<Mesh, MeshError> {
    let perimeter = outline.perimeter();
    let tol = 1e-9 * perimeter;
    let ends: Vec<f64> = electrodes.iter().flat_map(|e| [e.start(perimeter), e.end(perimeter)]).collect();
    let h_edge = params.grading.clamp(1e-3, 1.0) * h0;
    let spacing = |s: f64| {
        let d = ends.iter().map(|&e| arc_distance(s, e, perimeter)).fold(f64::INFINITY, f64::min);
        h0.min(h_edge + GROWTH * d)
    };

    let mut breaks: Vec<f64> = outline.corner_positions();
    breaks.extend(&ends);
    breaks.sort_by(f64::total_cmp);
    breaks.dedup_by(|a, b| (*a - *b).abs() < tol);
    if breaks.len() > 1 && breaks[0] + perimeter - breaks[breaks.len() - 1] < tol {
        breaks.pop();
    }
    if breaks.is_empty() {
        breaks.push(0.0);
    }

    let mut samples = Vec::new();
    for (i, &a) in breaks.iter().enumerate() {
        let b = if i + 1 < breaks.len() { breaks[i + 1] } else { breaks[0] + perimeter };
        samples.extend(sample_segment(a, b, &spacing));
    }
    let points: Vec<Point2<f64>> = samples
        .iter()
        .map(|&s| {
            let p = outline.point_at(s);
            Point2::new(p[0], p[1])
        })
        .collect();
    let n = points.len();
    let ring: Vec<[usize; 2]> = (0..n).map(|i| [i, (i + 1) % n]).collect();
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::bulk_load_cdt(points, ring)
        .map_err(|e| MeshError::Triangulation(insertion_problem(e).into()))?;

    let area_limit = 3f64.sqrt() / 4.0 * h0 * h0;
    let expected = (outline.area() / area_limit * 4.0) as usize + 4 * n + 1000;
    let result = cdt.refine(
        RefinementParameters::<f64>::new()
            .with_angle_limit(AngleLimit::from_deg(params.min_angle_deg))
            .with_max_allowed_area(area_limit)
            .with_max_additional_vertices(expected)
            .exclude_outer_faces(true),
    );
    if !result.refinement_complete {
        return Err(MeshError::RefinementIncomplete {
            vertices: cdt.num_vertices(),
            min_angle_deg: params.min_angle_deg,
        });
    }
    let excluded: HashSet<_> = result.excluded_faces.into_iter().collect();

    let mut index = vec![usize::MAX; cdt.num_vertices()];
    let mut nodes = Vec::with_capacity(cdt.num_vertices());
    let mut triangles = Vec::with_capacity(cdt.num_inner_faces());
    for face in cdt.inner_faces() {
        if excluded.contains(&face.fix()) {
            continue;
        }
        let tri = face.vertices().map(|v| {
            let i = v.fix().index();
            if index[i] == usize::MAX {
                index[i] = nodes.len();
                let p = v.position();
                nodes.push([p.x, p.y]);
            }
            index[i]
        });
        triangles.push(tri);
    }

    // Constraint edges get split during refinement, so electrode nodes are found by
    // geometry: every boundary node whose arc length lies on the electrode.
    let unassigned = Mesh::new(nodes, triangles, Vec::new())?;
    let mut boundary: Vec<(usize, f64)> = unassigned
        .boundary_edges()
        .iter()
        .map(|e| e[0])
        .map(|n| (n, outline.locate(unassigned.nodes()[n]).0))
        .collect();
    boundary.sort_by(|a, b| a.1.total_cmp(&b.1));
    let sets = electrodes
        .iter()
        .map(|e| {
            let mut set: Vec<(usize, f64)> = boundary
                .iter()
                .filter(|(_, s)| e.covers(*s, perimeter, tol))
                .map(|&(n, s)| (n, (s - e.start(perimeter) + tol).rem_euclid(perimeter)))
                .collect();
            set.sort_by(|a, b| a.1.total_cmp(&b.1));
            set.into_iter().map(|(n, _)| n).collect()
        })
        .collect();
    let Mesh { nodes, triangles, .. } = unassigned;
    Mesh::new(nodes, triangles, sets)
}

/// Arc lengths from `a` (included) to `b` (excluded) with steps following `spacing`.
fn sample_segment(a: f64, b: f64, spacing: &impl Fn(f64) -> f64) -> Vec<f64> {
    let length = b - a;
    let mut marks = vec![0.0];
    let mut s = a;
    while s < b {
        let next = s + spacing(s).max(length * 1e-6);
        // On a huge outline a step below the spacing of floating-point numbers near s would
        // not move it, and the loop would not end.
        if next == s {
            break;
        }
        s = next;
        marks.push(s - a);
    }
    // Stretch the marks so the last one lands on b, then drop it (it starts the next segment).
    let last = marks.len() - 1;
    let scale = if last > 1 && marks[last] - length > 0.5 * (marks[last] - marks[last - 1]) {
        marks.pop();
        length / marks[marks.len() - 1]
    } else {
        length / marks[last]
    };
    marks.pop();
    marks.iter().map(|m| a + m * scale).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper_square() -> (Outline, Vec<Electrode>) {
        let outline = Outline::Rectangle { width: 0.2, height: 0.2 };
        let electrodes = (0..16)
            .map(|i| {
                let side = (i / 4) as f64;
                Electrode { centre: side * 0.2 + 0.025 + 0.05 * (i % 4) as f64, width: 0.01 }
            })
            .collect::<Vec<_>>();
        (outline, electrodes)
    }

    #[test]
    fn sampling_lands_on_both_ends() {
        let s = sample_segment(1.0, 2.0, &|_| 0.3);
        assert_eq!(s[0], 1.0);
        assert!(s.windows(2).all(|w| w[1] > w[0]) && *s.last().unwrap() < 2.0);
        let steps: Vec<f64> = s.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(steps.iter().all(|d| (d - steps[0]).abs() < 1e-12), "{steps:?}");
    }

    #[test]
    fn paper_square_meets_count_angle_and_electrodes() {
        let (outline, electrodes) = paper_square();
        let mesh = Mesh::generate(&outline, &electrodes, &MeshParams::default()).unwrap();
        let n = mesh.triangles().len();
        assert!((3800..=4200).contains(&n), "{n} triangles");
        assert!(mesh.min_angle_deg() > 28.0, "min angle {}", mesh.min_angle_deg());
        let area: f64 = (0..n).map(|t| mesh.area(t)).sum();
        assert!((area - 0.04).abs() < 1e-12);
        for l in 0..16 {
            let len: f64 = mesh
                .electrode_edges(l)
                .iter()
                .map(|e| crate::geometry::dist(mesh.nodes()[e[0]], mesh.nodes()[e[1]]))
                .sum();
            assert!((len - 0.01).abs() < 1e-12, "electrode {} covers {len} m", l + 1);
        }
    }

    #[test]
    fn grading_puts_smaller_edges_at_electrodes() {
        let (outline, electrodes) = paper_square();
        let shortest_electrode_edge = |grading| {
            let params = MeshParams { grading, ..MeshParams::default() };
            let mesh = Mesh::generate(&outline, &electrodes, &params).unwrap();
            mesh.electrode_edges(0)
                .iter()
                .map(|e| crate::geometry::dist(mesh.nodes()[e[0]], mesh.nodes()[e[1]]))
                .fold(f64::INFINITY, f64::min)
        };
        assert!(shortest_electrode_edge(0.2) < 0.5 * shortest_electrode_edge(1.0));
    }
}
