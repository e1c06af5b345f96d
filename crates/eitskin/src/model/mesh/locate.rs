//! Point location on a mesh (a uniform grid of buckets) and the raster map built on it.

use super::Mesh;

/// The triangles of a mesh by the cells of a uniform grid over its box (about one triangle per
/// cell), each listed in every cell its bounding box meets; owns its data, so that it can live
/// beside the mesh it was built from.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleBuckets {
    lo: [f64; 2],
    cell: [f64; 2],
    dims: [usize; 2],
    start: Vec<usize>,
    items: Vec<usize>,
    /// Per item, the first cell (x, y) its triangle's box meets: a box query lists the triangle
    /// once, from the first of its cells inside the query.
    first: Vec<[u32; 2]>,
}

impl TriangleBuckets {
    /// Buckets the triangles of `mesh`.
    pub fn new(mesh: &Mesh) -> TriangleBuckets {
        let [lo, hi] = mesh.bounds();
        let side = (mesh.triangles().len() as f64).sqrt().ceil().max(1.0) as usize;
        let dims = [side, side];
        let cell = [
            ((hi[0] - lo[0]) / side as f64).max(f64::MIN_POSITIVE),
            ((hi[1] - lo[1]) / side as f64).max(f64::MIN_POSITIVE),
        ];
        let mut buckets =
            TriangleBuckets { lo, cell, dims, start: vec![0; side * side + 1], items: Vec::new(), first: Vec::new() };
        // Two passes (count, then fill) give a compressed bucket list without per-bucket vectors.
        for pass in 0..2 {
            let mut fill = buckets.start.clone();
            for t in 0..mesh.triangles().len() {
                let corners = mesh.corners(t);
                let (min, max) = corners.iter().fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(a, b), c| {
                    ([a[0].min(c[0]), a[1].min(c[1])], [b[0].max(c[0]), b[1].max(c[1])])
                });
                let [(i0, i1), (j0, j1)] = buckets.cell_range(min, max);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let b = j * side + i;
                        if pass == 0 {
                            buckets.start[b + 1] += 1;
                        } else {
                            buckets.items[fill[b]] = t;
                            buckets.first[fill[b]] = [i0 as u32, j0 as u32];
                            fill[b] += 1;
                        }
                    }
                }
            }
            if pass == 0 {
                for b in 0..side * side {
                    buckets.start[b + 1] += buckets.start[b];
                }
                buckets.items = vec![0; buckets.start[side * side]];
                buckets.first = vec![[0, 0]; buckets.start[side * side]];
            }
        }
        buckets
    }

    fn cell_of(&self, p: [f64; 2]) -> Option<(usize, usize)> {
        let fx = (p[0] - self.lo[0]) / self.cell[0];
        let fy = (p[1] - self.lo[1]) / self.cell[1];
        let eps = 1e-9;
        if fx < -eps || fy < -eps || fx > self.dims[0] as f64 + eps || fy > self.dims[1] as f64 + eps {
            return None;
        }
        let clamp = |f: f64, n: usize| (f.max(0.0) as usize).min(n - 1);
        Some((clamp(fx, self.dims[0]), clamp(fy, self.dims[1])))
    }

    /// The cells `[(first, last) in x, (first, last) in y]` the box `[min, max]` (m) meets.
    fn cell_range(&self, min: [f64; 2], max: [f64; 2]) -> [(usize, usize); 2] {
        let clamp = |f: f64, n: usize| (f.max(0.0) as usize).min(n - 1);
        let axis = |k: usize| {
            let f = |v: f64| (v - self.lo[k]) / self.cell[k];
            (clamp(f(min[k]) - 1e-9, self.dims[k]), clamp(f(max[k]) + 1e-9, self.dims[k]))
        };
        [axis(0), axis(1)]
    }

    /// The triangles listed in the cells of `p` (m); empty outside the grid.
    fn at(&self, p: [f64; 2]) -> &[usize] {
        match self.cell_of(p) {
            Some((i, j)) => {
                let b = j * self.dims[0] + i;
                &self.items[self.start[b]..self.start[b + 1]]
            }
            None => &[],
        }
    }

    /// The cells a query box `[min, max]` (m) meets, as [`TriangleBuckets::cell_range`]; `None`
    /// for a box that is empty (a min past its max, or NaN).
    fn query(&self, min: [f64; 2], max: [f64; 2]) -> Option<[(usize, usize); 2]> {
        (min[0] <= max[0] && min[1] <= max[1]).then(|| self.cell_range(min, max))
    }

    /// Every triangle whose bounding box may meet the box `[min, max]` (m), some more than
    /// once (a triangle is listed in each cell it meets), into `out` (cleared); none for a box
    /// that is empty (a min past its max, or NaN).
    pub fn near_into(&self, min: [f64; 2], max: [f64; 2], out: &mut Vec<usize>) {
        out.clear();
        let Some([(i0, i1), (j0, j1)]) = self.query(min, max) else { return };
        for j in j0..=j1 {
            let (from, to) = (self.start[j * self.dims[0] + i0], self.start[j * self.dims[0] + i1 + 1]);
            out.extend_from_slice(&self.items[from..to]);
        }
    }

    /// [`TriangleBuckets::near_into`], each triangle once: from the first cell inside the box
    /// that the triangle's own box meets (no sorting).
    pub fn near_once_into(&self, min: [f64; 2], max: [f64; 2], out: &mut Vec<usize>) {
        out.clear();
        let Some([(i0, i1), (j0, j1)]) = self.query(min, max) else { return };
        for j in j0..=j1 {
            for i in i0..=i1 {
                let b = j * self.dims[0] + i;
                let (from, to) = (self.start[b], self.start[b + 1]);
                for (&t, &[fi, fj]) in self.items[from..to].iter().zip(&self.first[from..to]) {
                    if (fi as usize).max(i0) == i && (fj as usize).max(j0) == j {
                        out.push(t);
                    }
                }
            }
        }
    }
}

/// Finds the triangle that holds a point, through a uniform grid of triangle buckets.
#[derive(Debug, Clone)]
pub struct PointLocator<'a> {
    mesh: &'a Mesh,
    buckets: TriangleBuckets,
}

impl<'a> PointLocator<'a> {
    /// Buckets the triangles of `mesh`, about one triangle per bucket.
    pub fn new(mesh: &'a Mesh) -> PointLocator<'a> {
        PointLocator { mesh, buckets: TriangleBuckets::new(mesh) }
    }

    /// The triangle holding `p` (in m), or `None` outside the mesh; a point on a shared edge
    /// goes to one of its triangles.
    pub fn locate(&self, p: [f64; 2]) -> Option<usize> {
        self.buckets.at(p).iter().copied().find(|&t| barycentric(self.mesh.corners(t), p).iter().all(|&w| w >= -1e-12))
    }
}

/// Barycentric coordinates of `p` in the triangle `[a, b, c]`.
pub fn barycentric([a, b, c]: [[f64; 2]; 3], p: [f64; 2]) -> [f64; 3] {
    let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    let wb = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / det;
    let wc = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / det;
    [1.0 - wb - wc, wb, wc]
}

/// Which triangle lies under each pixel centre of a grid over the mesh's bounding box.
///
/// Pixels are stored row by row, the first row at the top (largest y), as in an image.
#[derive(Debug, Clone, PartialEq)]
pub struct RasterMap {
    /// Columns and rows `[nx, ny]`.
    pub size: [usize; 2],
    /// The box covered, `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub bounds: [[f64; 2]; 2],
    /// Triangle under each pixel centre, row-major from the top; `None` outside the mesh (masked).
    pub triangle: Vec<Option<usize>>,
}

impl RasterMap {
    /// Maps an `nx × ny` grid over the bounding box of `mesh`.
    pub fn new(mesh: &Mesh, [nx, ny]: [usize; 2]) -> RasterMap {
        let bounds = mesh.bounds();
        let locator = PointLocator::new(mesh);
        let mut map = RasterMap { size: [nx, ny], bounds, triangle: Vec::with_capacity(nx * ny) };
        for row in 0..ny {
            for col in 0..nx {
                let p = map.pixel_centre(col, row);
                map.triangle.push(locator.locate(p));
            }
        }
        map
    }

    /// Centre of the pixel in column `col` and row `row` (row 0 at the top), in m.
    pub fn pixel_centre(&self, col: usize, row: usize) -> [f64; 2] {
        crate::image::pixel_centre(self.bounds, self.size, col, row)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Outline;
    use crate::mesh::MeshParams;

    #[test]
    fn locator_agrees_with_brute_force_on_a_disk() {
        let outline = Outline::Circle { radius: 1.0 };
        let params = MeshParams { triangles: 600, ..MeshParams::default() };
        let mesh = Mesh::generate(&outline, &[], &params).unwrap();
        let locator = PointLocator::new(&mesh);
        let inside = |t: usize, p| barycentric(mesh.corners(t), p).iter().all(|&w| w >= -1e-12);
        for k in 0..400 {
            let a = k as f64 * 0.7;
            let r = (k as f64 / 400.0).sqrt() * 1.02;
            let p = [r * a.cos(), r * a.sin()];
            let brute = (0..mesh.triangles().len()).find(|&t| inside(t, p));
            match (locator.locate(p), brute) {
                (Some(t), Some(_)) => assert!(inside(t, p)),
                (None, None) => {}
                other => panic!("point {p:?}: locator and brute force disagree: {other:?}"),
            }
        }
        assert_eq!(locator.locate(mesh.centroid(17)), Some(17));
    }

    /// Every triangle whose box meets a query box is listed (against the boxes themselves),
    /// boxes partly or wholly off the mesh included, and an empty box lists none.
    #[test]
    fn buckets_list_every_triangle_a_box_meets() {
        let mesh = Mesh::generate(
            &Outline::Rectangle { width: 2.0, height: 1.0 },
            &[],
            &MeshParams { triangles: 400, ..MeshParams::default() },
        )
        .unwrap();
        let buckets = TriangleBuckets::new(&mesh);
        let mut near = Vec::new();
        for (min, max) in [([-0.2, -0.1], [0.1, 0.05]), ([0.9, 0.4], [1.5, 0.9]), ([-3.0, 2.0], [-2.5, 2.5])] {
            buckets.near_into(min, max, &mut near);
            for t in 0..mesh.triangles().len() {
                let c = mesh.corners(t);
                let lo = [c[0][0].min(c[1][0]).min(c[2][0]), c[0][1].min(c[1][1]).min(c[2][1])];
                let hi = [c[0][0].max(c[1][0]).max(c[2][0]), c[0][1].max(c[1][1]).max(c[2][1])];
                if lo[0] <= max[0] && min[0] <= hi[0] && lo[1] <= max[1] && min[1] <= hi[1] {
                    assert!(near.contains(&t), "triangle {t} meets {min:?}–{max:?}");
                }
            }
            // Each once.
            let mut once = Vec::new();
            buckets.near_once_into(min, max, &mut once);
            once.sort_unstable();
            near.sort_unstable();
            near.dedup();
            assert_eq!(once, near);
        }
        // A box of negative size (a press of negative radius) or NaN meets nothing.
        for (min, max) in [([0.5, 2.0], [0.4, 2.0]), ([0.1, 0.1], [0.0, 0.2]), ([f64::NAN, 0.0], [0.1, 0.1])] {
            buckets.near_into(min, max, &mut near);
            assert!(near.is_empty(), "{min:?}–{max:?}");
            buckets.near_once_into(min, max, &mut near);
            assert!(near.is_empty(), "{min:?}–{max:?}");
        }
    }

    #[test]
    fn raster_masks_pixels_outside_a_disk() {
        let mesh = Mesh::generate(
            &Outline::Circle { radius: 1.0 },
            &[],
            &MeshParams { triangles: 400, ..MeshParams::default() },
        )
        .unwrap();
        let map = RasterMap::new(&mesh, [64, 64]);
        let inside = map.triangle.iter().filter(|t| t.is_some()).count() as f64;
        let share = inside / (64.0 * 64.0);
        assert!((share - std::f64::consts::PI / 4.0).abs() < 0.02, "{share}");
        assert_eq!(map.triangle[0], None, "top-left corner is outside the disk");
        assert!(map.pixel_centre(0, 0)[1] > 0.9);
    }
}
