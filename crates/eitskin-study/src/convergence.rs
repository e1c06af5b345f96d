//! Mesh-convergence studies: the same sensor meshed ever finer, each level's measurements and
//! setup time, and the converged answer they approach.
//!
//! The answer is analytic where one exists (a disk with homogeneous conductivity: the
//! Fourier-series complete electrode model of [`eitskin::analytic`]); otherwise it is the
//! Richardson extrapolation of the two finest levels, v* = v₂ + (v₂ − v₁)/(r^p − 1), with h
//! shrinking by r between them and p the order observed over the three finest levels.
//! Errors are max_m |v_m − v*_m| / max_m |v*_m|: relative to the largest value, so that
//! values near zero (four-terminal protocols) do not dominate.

use std::time::Instant;

use eitskin::analytic::DiskCem;
use eitskin::conductivity::{with_inclusions, Inclusion};
use eitskin::geometry::Outline;
use eitskin::protocol::Protocol;
use eitskin::spec::{SensorSpec, SpecError};

/// The elements of a study's forward model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Elements {
    /// Linear (P1), the forward model everything else uses.
    #[default]
    Linear,
    /// Quadratic (P2) on the same mesh ([`eitskin::forward::ForwardModel::measure_quadratic`]).
    Quadratic,
}

/// What a convergence study found: the errors of each level against the converged answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Convergence {
    /// Where the converged answer came from, in words.
    pub reference: &'static str,
    /// Order in h observed over the three finest levels for the values, if they converge.
    pub value_order: Option<f64>,
    /// The same for the difference signals.
    pub difference_order: Option<f64>,
    /// Per level, coarse to fine: triangles, setup time (s), relative errors of values and differences.
    pub levels: Vec<LevelError>,
}

/// One level's errors against the converged answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelError {
    /// Triangles in the mesh.
    pub triangles: usize,
    /// The whole setup chain, in s.
    pub setup_seconds: f64,
    /// Relative error of the values (see the module doc), dimensionless.
    pub value_error: f64,
    /// Relative error of the difference signals, dimensionless.
    pub difference_error: f64,
}

/// The inclusion of a study when none is given: radius 5 % of the width, a quarter of the width
/// right of the centre, half the background conductivity.
pub fn default_inclusion(spec: &SensorSpec) -> Inclusion {
    let [lo, hi] = spec.outline.bounds();
    let width = hi[0] - lo[0];
    Inclusion { centre: [0.25 * width, 0.0], radius: 0.05 * width, conductivity: 0.5 * spec.conductivity }
}

/// Meshes `spec` at each count of `triangles` (coarse to fine, at least 3), measures it with
/// `elements`, with and without `inclusion`, and gives each level's error against the analytic answer where there is
/// one and the Richardson extrapolation of the two finest levels otherwise, with the orders
/// observed over the three finest; `None` with fewer than 3 levels.
pub fn study(
    spec: &SensorSpec,
    triangles: &[usize],
    inclusion: Inclusion,
    elements: Elements,
) -> Result<Option<Convergence>, SpecError> {
    if triangles.len() < 3 {
        return Ok(None);
    }
    let levels = levels(spec, triangles, &[inclusion], elements)?;
    let n = levels.len();
    let tri = |k: usize| levels[k].triangles;
    let order_of = |f: fn(&Level) -> &[f64]| {
        observed_order([f(&levels[n - 3]), f(&levels[n - 2]), f(&levels[n - 1])], [tri(n - 3), tri(n - 2), tri(n - 1)])
    };
    let value_order = order_of(|l| &l.values);
    let difference_order = order_of(|l| &l.difference);
    let extrapolate = |f: fn(&Level) -> &[f64], order: Option<f64>| {
        let ratio = (tri(n - 1) as f64 / tri(n - 2) as f64).sqrt();
        richardson(f(&levels[n - 2]), f(&levels[n - 1]), ratio, order.unwrap_or(1.0).max(0.5))
    };
    let (reference, value_truth) = match disk_values(spec)? {
        Some(v) => ("analytic (Fourier series) for values, Richardson for differences", v),
        None => ("Richardson extrapolation of the two finest levels", extrapolate(|l| &l.values, value_order)),
    };
    let difference_truth = extrapolate(|l| &l.difference, difference_order);
    let levels = levels
        .iter()
        .map(|l| LevelError {
            triangles: l.triangles,
            setup_seconds: l.setup_seconds,
            value_error: relative_error(&l.values, &value_truth),
            difference_error: relative_error(&l.difference, &difference_truth),
        })
        .collect();
    Ok(Some(Convergence { reference, value_order, difference_order, levels }))
}

/// One refinement level: its mesh size, setup time and results.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// Triangles in the mesh.
    pub triangles: usize,
    /// The whole setup chain (mesh, model, assembly, factorisation, solves, measurements), in s.
    pub setup_seconds: f64,
    /// Measurements with the background conductivity, in V at 1 A (Ω).
    pub values: Vec<f64>,
    /// Measurements with the inclusions minus `values`, in V at 1 A (empty without inclusions).
    pub difference: Vec<f64>,
}

/// Meshes `spec` at about each count of `triangles` and measures it with `elements`, with and
/// without `inclusions`.
pub fn levels(
    spec: &SensorSpec,
    triangles: &[usize],
    inclusions: &[Inclusion],
    elements: Elements,
) -> Result<Vec<Level>, SpecError> {
    let measure = |model: &eitskin::forward::ForwardModel, sigma: &[f64]| match elements {
        Elements::Linear => model.measure(sigma),
        Elements::Quadratic => model.measure_quadratic(sigma),
    };
    let mut out = Vec::with_capacity(triangles.len());
    for &n in triangles {
        let mut spec = spec.clone();
        spec.mesh.triangles = n;
        spec.mesh.max_element_size = None;
        let start = Instant::now();
        let model = spec.forward_model()?;
        let values = measure(&model, &spec.homogeneous(model.mesh()))?;
        let setup_seconds = start.elapsed().as_secs_f64();
        let difference = if inclusions.is_empty() {
            Vec::new()
        } else {
            let sigma = with_inclusions(model.mesh(), spec.conductivity, inclusions);
            measure(&model, &sigma)?.iter().zip(&values).map(|(a, b)| a - b).collect()
        };
        out.push(Level { triangles: model.mesh().triangles().len(), setup_seconds, values, difference });
    }
    Ok(out)
}

/// The exact homogeneous measurements of a disk sensor with complete electrodes (Fourier series,
/// extrapolated in the number of modes), or `None` for other outlines or point electrodes.
pub fn disk_values(spec: &SensorSpec) -> Result<Option<Vec<f64>>, SpecError> {
    let Outline::Circle { radius } = spec.outline else { return Ok(None) };
    if spec.electrodes.point {
        return Ok(None);
    }
    let cem = DiskCem {
        radius,
        conductivity: spec.conductivity,
        thickness: spec.thickness,
        centres: spec.electrode_positions()?.iter().map(|e| e.centre / radius).collect(),
        width: spec.electrodes.width,
        contact_impedance: spec.electrodes.contact_impedance,
    };
    let protocol = spec.protocol()?;
    let currents: Vec<&[f64]> = protocol.stimulations().iter().map(Vec::as_slice).collect();
    let at = |modes| measurements(&protocol, &cem.electrode_voltages_many(&currents, modes));
    // The series converges as N⁻² (a little slower before that): one Richardson step from
    // 1200 and 2400 modes leaves about 1e-5 of the values.
    Ok(Some(richardson(&at(1200), &at(2400), 2.0, 2.0)))
}

/// A protocol's measurements from the electrode voltages (V) of each of its stimulations.
pub fn measurements(protocol: &Protocol, per_stimulation: &[Vec<f64>]) -> Vec<f64> {
    protocol
        .measurements()
        .iter()
        .map(|m| m.weights.iter().zip(&per_stimulation[m.stimulation]).map(|(w, u)| w * u).sum())
        .collect()
}

/// v₂ + (v₂ − v₁)/(ratio^order − 1): the extrapolated limit of values converging as h^order
/// when h shrinks by `ratio` from `coarse` to `fine`.
pub fn richardson(coarse: &[f64], fine: &[f64], ratio: f64, order: f64) -> Vec<f64> {
    let k = 1.0 / (ratio.powf(order) - 1.0);
    fine.iter().zip(coarse).map(|(f, c)| f + (f - c) * k).collect()
}

/// max |a − b| / max |b|: the error of `a` relative to the largest value of `reference`.
pub fn relative_error(a: &[f64], reference: &[f64]) -> f64 {
    let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(reference).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
}

/// The order p in h observed over three levels, from the differences between them
/// (h ∝ triangles^(−1/2)); `None` when the differences do not shrink.
pub fn observed_order(levels: [&[f64]; 3], triangles: [usize; 3]) -> Option<f64> {
    let gap = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let (d1, d2) = (gap(levels[1], levels[0]), gap(levels[2], levels[1]));
    let r1 = (triangles[1] as f64 / triangles[0] as f64).sqrt();
    let r2 = (triangles[2] as f64 / triangles[1] as f64).sqrt();
    if !(d2 < d1 && d2 > 0.0) {
        return None;
    }
    // d1/d2 = r^p when both steps shrink h by the same r; for unequal steps, take their
    // geometric mean.
    let r = (r1 * r2).sqrt();
    Some((d1 / d2).ln() / r.ln())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn richardson_removes_the_leading_error_term() {
        // v(h) = 3 + 0.5·h²: exact limit from h = 0.2 and 0.1.
        let v = |h: f64| 3.0 + 0.5 * h * h;
        let limit = richardson(&[v(0.2)], &[v(0.1)], 2.0, 2.0);
        assert!((limit[0] - 3.0).abs() < 1e-14);
    }

    #[test]
    fn order_of_a_known_sequence() {
        // Values converging as h^1.5 with h ∝ N^(−1/2).
        let at = |n: f64| vec![1.0 + n.powf(-0.75)];
        let (a, b, c) = (at(1000.0), at(4000.0), at(16000.0));
        let p = observed_order([&a, &b, &c], [1000, 4000, 16000]).unwrap();
        assert!((p - 1.5).abs() < 1e-9, "{p}");
    }
}
