//! Outlines of the sheet and electrodes on its boundary, in metres.
//!
//! A boundary is walked counter-clockwise by its arc length `s ∈ [0, perimeter)`:
//! a rectangle from its bottom-left corner, a circle from the angle 0 (the point `(r, 0)`),
//! a polygon from its first point. An [`Electrode`] is an interval of arc length; intervals
//! are taken modulo the perimeter, so an electrode may straddle `s = 0`.

use std::f64::consts::PI;

/// The shape of the sheet, centred on the origin, in metres.
#[derive(Debug, Clone, PartialEq)]
pub enum Outline {
    /// An axis-aligned rectangle centred on the origin; width along x, height along y (m).
    Rectangle {
        /// Extent along x, in m.
        width: f64,
        /// Extent along y, in m.
        height: f64,
    },
    /// A disk centred on the origin, radius in m.
    Circle {
        /// Radius, in m.
        radius: f64,
    },
    /// A simple polygon with counter-clockwise vertices, in m.
    Polygon {
        /// Vertices `[x, y]` in m, counter-clockwise, not repeating the first.
        points: Vec<[f64; 2]>,
    },
}

impl Outline {
    /// Length of the boundary, in m.
    pub fn perimeter(&self) -> f64 {
        match self {
            Outline::Rectangle { width, height } => 2.0 * (width + height),
            Outline::Circle { radius } => 2.0 * PI * radius,
            Outline::Polygon { points } => polygon_edges(points).map(|(a, b)| dist(a, b)).sum(),
        }
    }

    /// Enclosed area, in m².
    pub fn area(&self) -> f64 {
        match self {
            Outline::Rectangle { width, height } => width * height,
            Outline::Circle { radius } => PI * radius * radius,
            Outline::Polygon { points } => signed_area(points),
        }
    }

    /// Bounding box `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub fn bounds(&self) -> [[f64; 2]; 2] {
        match self {
            Outline::Rectangle { width, height } => [[-width / 2.0, -height / 2.0], [width / 2.0, height / 2.0]],
            Outline::Circle { radius } => [[-radius, -radius], [*radius, *radius]],
            Outline::Polygon { points } => {
                points.iter().fold([[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]], |[lo, hi], p| {
                    [[lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])]]
                })
            }
        }
    }

    /// The corners as polygon vertices (rectangle and polygon); empty for a circle.
    pub fn corners(&self) -> Vec<[f64; 2]> {
        match self {
            Outline::Rectangle { width, height } => {
                let (w, h) = (width / 2.0, height / 2.0);
                vec![[-w, -h], [w, -h], [w, h], [-w, h]]
            }
            Outline::Circle { .. } => Vec::new(),
            Outline::Polygon { points } => points.clone(),
        }
    }

    /// The boundary as a closed line to draw, in m: the corners with the first again at the end,
    /// or for a circle `circle_points` + 1 points evenly spaced.
    pub fn ring(&self, circle_points: usize) -> Vec<[f64; 2]> {
        let corners = self.corners();
        if corners.is_empty() {
            let step = self.perimeter() / circle_points.max(3) as f64;
            return (0..=circle_points.max(3)).map(|k| self.point_at(k as f64 * step)).collect();
        }
        corners.iter().chain(corners.first()).copied().collect()
    }

    /// Arc length of each corner, in m (empty for a circle).
    pub fn corner_positions(&self) -> Vec<f64> {
        let corners = self.corners();
        let mut s = 0.0;
        let mut out = Vec::with_capacity(corners.len());
        for (a, b) in polygon_edges(&corners) {
            out.push(s);
            s += dist(a, b);
        }
        out
    }

    /// The boundary point at arc length `s` (taken modulo the perimeter), in m.
    pub fn point_at(&self, s: f64) -> [f64; 2] {
        let s = s.rem_euclid(self.perimeter());
        if let Outline::Circle { radius } = self {
            let theta = s / radius;
            return [radius * theta.cos(), radius * theta.sin()];
        }
        let corners = self.corners();
        let mut start = 0.0;
        for (a, b) in polygon_edges(&corners) {
            let len = dist(a, b);
            if s <= start + len {
                let t = ((s - start) / len).clamp(0.0, 1.0);
                return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            }
            start += len;
        }
        corners[0]
    }

    /// Arc length, in m, where the ray from the origin (the outline's centre) at `angle_deg`
    /// degrees from the +x axis, counter-clockwise, first meets the boundary; `None` when it
    /// misses (a polygon that does not surround the origin).
    pub fn arc_length_at_angle(&self, angle_deg: f64) -> Option<f64> {
        let theta = angle_deg.to_radians();
        if let Outline::Circle { radius } = self {
            return Some(radius * theta.rem_euclid(2.0 * PI));
        }
        let direction = [theta.cos(), theta.sin()];
        let corners = self.corners();
        let mut best: Option<(f64, f64)> = None;
        let mut start = 0.0;
        for (a, b) in polygon_edges(&corners) {
            let len = dist(a, b);
            let edge = [b[0] - a[0], b[1] - a[1]];
            // Solve t·direction = a + u·edge for the ray parameter t (m) and the edge's u ∈ [0, 1].
            let det = edge[0] * direction[1] - edge[1] * direction[0];
            if det.abs() > 1e-15 * len {
                let t = (edge[0] * a[1] - edge[1] * a[0]) / det;
                let u = (direction[0] * a[1] - direction[1] * a[0]) / det;
                if t > 0.0 && (-1e-12..=1.0 + 1e-12).contains(&u) && best.is_none_or(|(t_best, _)| t < t_best) {
                    best = Some((t, start + u.clamp(0.0, 1.0) * len));
                }
            }
            start += len;
        }
        best.map(|(_, s)| s.rem_euclid(start))
    }

    /// Arc length of the boundary point nearest to `p`, and the distance to it, in m.
    pub fn locate(&self, p: [f64; 2]) -> (f64, f64) {
        if let Outline::Circle { radius } = self {
            let theta = p[1].atan2(p[0]).rem_euclid(2.0 * PI);
            return (radius * theta, (p[0].hypot(p[1]) - radius).abs());
        }
        let corners = self.corners();
        let mut best = (0.0, f64::INFINITY);
        let mut start = 0.0;
        for (a, b) in polygon_edges(&corners) {
            let len = dist(a, b);
            let t = (((p[0] - a[0]) * (b[0] - a[0]) + (p[1] - a[1]) * (b[1] - a[1])) / (len * len)).clamp(0.0, 1.0);
            let q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            let d = dist(p, q);
            if d < best.1 {
                best = (start + t * len, d);
            }
            start += len;
        }
        best
    }

    /// Whether `p` lies inside the outline (points on the boundary may go either way).
    pub fn contains(&self, p: [f64; 2]) -> bool {
        match self {
            Outline::Rectangle { width, height } => p[0].abs() <= width / 2.0 && p[1].abs() <= height / 2.0,
            Outline::Circle { radius } => p[0].hypot(p[1]) <= *radius,
            Outline::Polygon { points } => {
                let mut inside = false;
                for (a, b) in polygon_edges(points) {
                    if (a[1] > p[1]) != (b[1] > p[1]) {
                        let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                        if p[0] < x {
                            inside = !inside;
                        }
                    }
                }
                inside
            }
        }
    }
}

/// One electrode: an interval of the boundary's arc length, in m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Electrode {
    /// Arc length of the electrode's centre, in m, in `[0, perimeter)`.
    pub centre: f64,
    /// Length along the boundary, in m (0 for a point electrode).
    pub width: f64,
}

impl Electrode {
    /// Arc length where the electrode starts (counter-clockwise), in m, modulo `perimeter`.
    pub fn start(&self, perimeter: f64) -> f64 {
        (self.centre - self.width / 2.0).rem_euclid(perimeter)
    }

    /// Arc length where the electrode ends, in m, modulo `perimeter`.
    pub fn end(&self, perimeter: f64) -> f64 {
        (self.centre + self.width / 2.0).rem_euclid(perimeter)
    }

    /// Whether arc length `s` lies on the electrode, with a tolerance `tol` in m.
    pub fn covers(&self, s: f64, perimeter: f64, tol: f64) -> bool {
        arc_distance(s, self.centre, perimeter) <= self.width / 2.0 + tol
    }
}

/// Distance between two arc lengths along a closed boundary, in m.
pub fn arc_distance(a: f64, b: f64, perimeter: f64) -> f64 {
    let d = (a - b).rem_euclid(perimeter);
    d.min(perimeter - d)
}

/// Consecutive vertex pairs of a closed polygon, the last joined to the first.
pub fn polygon_edges(points: &[[f64; 2]]) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
    (0..points.len()).map(move |i| (points[i], points[(i + 1) % points.len()]))
}

/// Signed area of a polygon, positive when counter-clockwise, in m².
pub fn signed_area(points: &[[f64; 2]]) -> f64 {
    0.5 * polygon_edges(points).map(|(a, b)| a[0] * b[1] - b[0] * a[1]).sum::<f64>()
}

/// Euclidean distance between two points, in m.
pub fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The first pair of non-adjacent polygon edges that cross or touch, as 0-based edge indices
/// (edge `i` joins vertex `i` to vertex `i + 1`).
pub fn first_crossing(points: &[[f64; 2]]) -> Option<(usize, usize)> {
    let n = points.len();
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            if adjacent {
                continue;
            }
            let (a, b) = (points[i], points[(i + 1) % n]);
            let (c, d) = (points[j], points[(j + 1) % n]);
            if segments_intersect(a, b, c, d) {
                return Some((i, j));
            }
        }
    }
    None
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn segments_intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    let on = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        r[0] >= p[0].min(q[0]) && r[0] <= p[0].max(q[0]) && r[1] >= p[1].min(q[1]) && r[1] <= p[1].max(q[1])
    };
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    (d1 == 0.0 && on(c, d, a)) || (d2 == 0.0 && on(c, d, b)) || (d3 == 0.0 && on(a, b, c)) || (d4 == 0.0 && on(a, b, d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_walk_starts_bottom_left_and_turns_counter_clockwise() {
        let sq = Outline::Rectangle { width: 2.0, height: 2.0 };
        assert_eq!(sq.point_at(0.0), [-1.0, -1.0]);
        assert_eq!(sq.point_at(0.5), [-0.5, -1.0]);
        assert_eq!(sq.point_at(2.5), [1.0, -0.5]);
        assert_eq!(sq.point_at(5.0), [0.0, 1.0]);
        let (s, d) = sq.locate([0.3, 1.2]);
        assert!((s - 4.7).abs() < 1e-12 && (d - 0.2).abs() < 1e-12);
    }

    #[test]
    fn rays_from_the_centre_meet_the_boundary_where_expected() {
        let sq = Outline::Rectangle { width: 2.0, height: 2.0 };
        let at = |o: &Outline, deg: f64| o.point_at(o.arc_length_at_angle(deg).unwrap());
        let close = |p: [f64; 2], q: [f64; 2]| dist(p, q) < 1e-12;
        assert!(close(at(&sq, 0.0), [1.0, 0.0]));
        assert!(close(at(&sq, 90.0), [0.0, 1.0]));
        assert!(close(at(&sq, 225.0), [-1.0, -1.0]), "{:?}", at(&sq, 225.0));
        assert!(close(at(&sq, -90.0), [0.0, -1.0]));
        let wide = Outline::Rectangle { width: 4.0, height: 2.0 };
        assert!(close(at(&wide, 45.0), [1.0, 1.0]));
        let c = Outline::Circle { radius: 0.5 };
        assert!(close(at(&c, 120.0), [0.5 * 120f64.to_radians().cos(), 0.5 * 120f64.to_radians().sin()]));
        let triangle = Outline::Polygon { points: vec![[-1.0, -1.0], [2.0, -1.0], [-1.0, 2.0]] };
        assert!(close(at(&triangle, 45.0), [0.5, 0.5]));
        assert!(close(at(&triangle, 180.0), [-1.0, 0.0]));
        let off_centre = Outline::Polygon { points: vec![[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]] };
        assert_eq!(off_centre.arc_length_at_angle(-90.0), None);
    }

    #[test]
    fn circle_locate_inverts_point_at() {
        let c = Outline::Circle { radius: 0.5 };
        for s in [0.0, 0.3, 1.0, 3.0] {
            let (back, d) = c.locate(c.point_at(s));
            assert!((back - s).abs() < 1e-12 && d < 1e-12);
        }
    }

    #[test]
    fn bow_tie_crosses_itself() {
        let bow = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        assert_eq!(first_crossing(&bow), Some((0, 2)));
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert_eq!(first_crossing(&square), None);
        assert!(signed_area(&square) > 0.0);
    }

    #[test]
    fn electrode_straddling_the_start_covers_both_ends() {
        let e = Electrode { centre: 0.05, width: 0.2 };
        assert!(e.covers(7.98, 8.0, 0.0) && e.covers(0.1, 8.0, 0.0) && !e.covers(0.2, 8.0, 0.0));
    }
}
