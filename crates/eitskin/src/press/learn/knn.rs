//! k-nearest neighbours in z-scored channel space: the floor every learned method must beat.

/// The training points (rows of `dimensions`) and their targets, and k.
#[derive(Debug, Clone, PartialEq)]
pub struct Knn {
    k: usize,
    dimensions: usize,
    points: Vec<f64>,
    targets: Vec<Vec<f64>>,
}

impl Knn {
    /// Keeps `points` (z-scored rows) and their `targets` (one row of outputs each); k ≥ 1.
    pub fn new(k: usize, points: &[Vec<f64>], targets: &[Vec<f64>]) -> Knn {
        let dimensions = points.first().map_or(0, Vec::len);
        Knn { k: k.max(1), dimensions, points: points.concat(), targets: targets.to_vec() }
    }

    /// k.
    pub fn k(&self) -> usize {
        self.k
    }

    /// The mean target of the k nearest training points to `z`, into `out`; `nearest` is a
    /// scratch of (squared distance, index) pairs, grown once.
    pub fn predict_into(&self, z: &[f64], nearest: &mut Vec<(f64, usize)>, out: &mut [f64]) {
        nearest.clear();
        for (i, point) in self.points.chunks_exact(self.dimensions.max(1)).enumerate() {
            let d: f64 = point.iter().zip(z).map(|(p, q)| (p - q) * (p - q)).sum();
            nearest.push((d, i));
        }
        let k = self.k.min(nearest.len());
        if k == 0 {
            out.fill(f64::NAN);
            return;
        }
        nearest.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
        out.fill(0.0);
        for &(_, i) in &nearest[..k] {
            for (o, t) in out.iter_mut().zip(&self.targets[i]) {
                *o += t / k as f64;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_points_answer() {
        let points: Vec<Vec<f64>> = (0..10).map(|i| vec![i as f64, 0.0]).collect();
        let targets: Vec<Vec<f64>> = (0..10).map(|i| vec![10.0 * i as f64]).collect();
        let knn = Knn::new(2, &points, &targets);
        let (mut scratch, mut out) = (Vec::new(), [0.0]);
        knn.predict_into(&[3.2, 0.1], &mut scratch, &mut out);
        assert_eq!(out[0], 35.0); // points 3 and 4
    }
}
