//! Triangle meshes of the sheet: nodes, counter-clockwise triangles, electrode node sets.
//!
//! A [`Mesh`] is plain, checked data. Make one with [`Mesh::generate`] (constrained Delaunay
//! triangulation and Ruppert refinement, graded toward the electrode edges), or from another
//! tool's arrays with [`Mesh::new`]. [`PointLocator`] finds the triangle holding a point and
//! [`RasterMap`] the triangle under each pixel of a grid.

mod generate;
mod locate;

pub use generate::MeshParams;
pub use locate::{barycentric, PointLocator, RasterMap, TriangleBuckets};

use std::collections::HashMap;
use thiserror::Error;

/// What is wrong with a mesh; indices in messages are 0-based node and triangle indices,
/// electrodes are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    /// A mesh needs nodes and triangles.
    #[error("a mesh needs at least 3 nodes and 1 triangle, got {nodes} nodes and {triangles} triangles")]
    Empty {
        /// Node count.
        nodes: usize,
        /// Triangle count.
        triangles: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("node {node} has a coordinate that is not finite")]
    NotFinite {
        /// 0-based node index.
        node: usize,
    },
    /// A triangle names a node that does not exist.
    #[error("triangle {triangle} names node {node}, but the mesh has {count} nodes")]
    NoSuchNode {
        /// 0-based triangle index.
        triangle: usize,
        /// The node index found.
        node: usize,
        /// Node count.
        count: usize,
    },
    /// A triangle has no area.
    #[error("triangle {triangle} has zero area (its corners are collinear or repeated)")]
    Degenerate {
        /// 0-based triangle index.
        triangle: usize,
    },
    /// An electrode node is not on the boundary, or an electrode has no node.
    #[error("electrode {electrode}: node {node} is not on the mesh boundary")]
    ElectrodeOffBoundary {
        /// 1-based electrode number.
        electrode: usize,
        /// 0-based node index.
        node: usize,
    },
    /// An electrode with several nodes must cover at least one boundary edge.
    #[error("electrode {electrode} has {nodes} nodes but no boundary edge joins two of them")]
    ElectrodeWithoutEdge {
        /// 1-based electrode number.
        electrode: usize,
        /// Its node count.
        nodes: usize,
    },
    /// An electrode has no node at all.
    #[error("electrode {electrode} has no node")]
    ElectrodeEmpty {
        /// 1-based electrode number.
        electrode: usize,
    },
    /// Refinement stopped before meeting the angle bound (too many vertices asked for).
    #[error("mesh refinement stopped at {vertices} vertices before reaching a {min_angle_deg}° minimum angle; ask for fewer triangles or a smaller angle")]
    RefinementIncomplete {
        /// Vertices when it stopped.
        vertices: usize,
        /// The angle bound asked for, in degrees.
        min_angle_deg: f64,
    },
    /// The triangulator refused the boundary.
    #[error("the boundary could not be triangulated: {0}")]
    Triangulation(String),
}

/// A triangle mesh of the sheet, in metres, with the boundary nodes of each electrode.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    nodes: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
    electrodes: Vec<Vec<usize>>,
    boundary_edges: Vec<[usize; 2]>,
}

impl Mesh {
    /// A checked mesh: nodes in m, triangles as node indices (clockwise ones are turned
    /// counter-clockwise), and per electrode its boundary nodes (one node: a point electrode).
    pub fn new(
        nodes: Vec<[f64; 2]>,
        mut triangles: Vec<[usize; 3]>,
        electrodes: Vec<Vec<usize>>,
    ) -> Result<Mesh, MeshError> {
        if nodes.len() < 3 || triangles.is_empty() {
            return Err(MeshError::Empty { nodes: nodes.len(), triangles: triangles.len() });
        }
        if let Some(node) = nodes.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
            return Err(MeshError::NotFinite { node });
        }
        for (t, tri) in triangles.iter_mut().enumerate() {
            if let Some(&node) = tri.iter().find(|&&n| n >= nodes.len()) {
                return Err(MeshError::NoSuchNode { triangle: t, node, count: nodes.len() });
            }
            let area = signed_area(&nodes, *tri);
            let scale = edge_scale(&nodes, *tri);
            if area.abs() <= 1e-14 * scale * scale {
                return Err(MeshError::Degenerate { triangle: t });
            }
            if area < 0.0 {
                tri.swap(1, 2);
            }
        }
        let boundary_edges = find_boundary_edges(&triangles);
        let mut on_boundary = vec![false; nodes.len()];
        for e in &boundary_edges {
            on_boundary[e[0]] = true;
            on_boundary[e[1]] = true;
        }
        let mesh = Mesh { nodes, triangles, electrodes, boundary_edges };
        for (l, set) in mesh.electrodes.iter().enumerate() {
            if set.is_empty() {
                return Err(MeshError::ElectrodeEmpty { electrode: l + 1 });
            }
            if let Some(&node) = set.iter().find(|&&n| n >= on_boundary.len() || !on_boundary[n]) {
                return Err(MeshError::ElectrodeOffBoundary { electrode: l + 1, node });
            }
            if set.len() > 1 && mesh.electrode_edges(l).is_empty() {
                return Err(MeshError::ElectrodeWithoutEdge { electrode: l + 1, nodes: set.len() });
            }
        }
        Ok(mesh)
    }

    /// Node coordinates `[x, y]`, in m.
    pub fn nodes(&self) -> &[[f64; 2]] {
        &self.nodes
    }

    /// Triangles as counter-clockwise node indices.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Boundary nodes of each electrode (0-based electrode index).
    pub fn electrodes(&self) -> &[Vec<usize>] {
        &self.electrodes
    }

    /// Boundary edges, each oriented as in its (counter-clockwise) triangle.
    pub fn boundary_edges(&self) -> &[[usize; 2]] {
        &self.boundary_edges
    }

    /// The boundary edges whose two ends both belong to electrode `l` (0-based): the surface
    /// the complete electrode model acts on.
    pub fn electrode_edges(&self, l: usize) -> Vec<[usize; 2]> {
        let set = &self.electrodes[l];
        self.boundary_edges.iter().filter(|e| set.contains(&e[0]) && set.contains(&e[1])).copied().collect()
    }

    /// The corner coordinates of triangle `t`, in m.
    pub fn corners(&self, t: usize) -> [[f64; 2]; 3] {
        self.triangles[t].map(|n| self.nodes[n])
    }

    /// Area of triangle `t`, in m².
    pub fn area(&self, t: usize) -> f64 {
        signed_area(&self.nodes, self.triangles[t])
    }

    /// Centroid of triangle `t`, in m.
    pub fn centroid(&self, t: usize) -> [f64; 2] {
        let [a, b, c] = self.corners(t);
        [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
    }

    /// The triangles whose centroid lies within `radius` (m) of `centre` (m), or the one nearest
    /// to it when none does: a small disk on the mesh, never empty for a mesh with triangles.
    pub fn triangles_near(&self, centre: [f64; 2], radius: f64) -> Vec<usize> {
        let n = self.triangles().len();
        let distance = |t: usize| {
            let [x, y] = self.centroid(t);
            (x - centre[0]).hypot(y - centre[1])
        };
        let inside: Vec<usize> = (0..n).filter(|&t| distance(t) <= radius).collect();
        if !inside.is_empty() {
            return inside;
        }
        (0..n).min_by(|&a, &b| distance(a).total_cmp(&distance(b))).into_iter().collect()
    }

    /// The longest edge of any triangle, in m.
    pub fn longest_edge(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let c = self.corners(t);
                (0..3).map(|k| crate::geometry::dist(c[k], c[(k + 1) % 3])).fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }

    /// Bounding box of the nodes, `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub fn bounds(&self) -> [[f64; 2]; 2] {
        self.nodes.iter().fold([[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]], |[lo, hi], p| {
            [[lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])]]
        })
    }

    /// The smallest interior angle over all triangles, in degrees.
    pub fn min_angle_deg(&self) -> f64 {
        let mut min = f64::INFINITY;
        for t in 0..self.triangles.len() {
            let p = self.corners(t);
            for i in 0..3 {
                let (a, b, c) = (p[i], p[(i + 1) % 3], p[(i + 2) % 3]);
                let u = [b[0] - a[0], b[1] - a[1]];
                let v = [c[0] - a[0], c[1] - a[1]];
                let cos = (u[0] * v[0] + u[1] * v[1]) / (u[0].hypot(u[1]) * v[0].hypot(v[1]));
                min = min.min(cos.clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
        min
    }
}

fn signed_area(nodes: &[[f64; 2]], [a, b, c]: [usize; 3]) -> f64 {
    let (a, b, c) = (nodes[a], nodes[b], nodes[c]);
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
}

fn edge_scale(nodes: &[[f64; 2]], tri: [usize; 3]) -> f64 {
    let p = tri.map(|n| nodes[n]);
    (0..3).map(|i| crate::geometry::dist(p[i], p[(i + 1) % 3])).fold(0.0, f64::max)
}

/// Edges that belong to exactly one triangle, oriented as in that triangle.
fn find_boundary_edges(triangles: &[[usize; 3]]) -> Vec<[usize; 2]> {
    let mut count: HashMap<[usize; 2], (usize, [usize; 2])> = HashMap::new();
    for tri in triangles {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            count.entry([a.min(b), a.max(b)]).or_insert((0, [a, b])).0 += 1;
        }
    }
    let mut edges: Vec<[usize; 2]> = count.into_values().filter(|(n, _)| *n == 1).map(|(_, e)| e).collect();
    edges.sort_unstable();
    edges
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_square() -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
        (vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], vec![[0, 1, 2], [0, 3, 2]])
    }

    #[test]
    fn clockwise_triangles_are_turned_and_boundary_found() {
        let (nodes, tris) = unit_square();
        let mesh = Mesh::new(nodes, tris, vec![vec![0, 1], vec![2]]).unwrap();
        assert!((0..2).all(|t| mesh.area(t) > 0.0));
        assert_eq!(mesh.boundary_edges().len(), 4);
        assert_eq!(mesh.electrode_edges(0), vec![[0, 1]]);
        assert!((mesh.min_angle_deg() - 45.0).abs() < 1e-9);
    }

    #[test]
    fn bad_meshes_say_where() {
        let (nodes, _) = unit_square();
        let err = Mesh::new(nodes.clone(), vec![[0, 1, 7]], vec![]).unwrap_err();
        assert_eq!(err.to_string(), "triangle 0 names node 7, but the mesh has 4 nodes");
        let err = Mesh::new(nodes.clone(), vec![[0, 1, 2], [0, 0, 3]], vec![]).unwrap_err();
        assert_eq!(err, MeshError::Degenerate { triangle: 1 });
        let five = [nodes.clone(), vec![[0.5, 0.5]]].concat();
        let tris = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        let err = Mesh::new(five, tris, vec![vec![0, 1], vec![4]]).unwrap_err();
        assert_eq!(err, MeshError::ElectrodeOffBoundary { electrode: 2, node: 4 });
        let err = Mesh::new(nodes, unit_square().1, vec![vec![0, 2]]).unwrap_err();
        assert_eq!(err, MeshError::ElectrodeWithoutEdge { electrode: 1, nodes: 2 });
    }
}
