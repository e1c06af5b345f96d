//! Analytic reference solutions on a disk, to check the finite-element forward model.
//!
//! The sheet is the disk |x| < R of thickness t and conductivity σ: −∇·(σt∇u) = 0 inside. It is
//! the 2-D problem with conductivity k = σt (S) and, for electrodes, contact impedance z/t (Ω·m),
//! so every voltage scales as 1/t. Angles θ are counter-clockwise from +x, in radians.
//!
//! **Point electrodes** (Neumann Green's function of the disk). With a = R(cos θ₊, sin θ₊) the
//! source of 1 A and b = R(cos θ₋, sin θ₋) the sink,
//!
//!   u(x) = ln(|x − b| / |x − a|) / (πσt).
//!
//! On |x| = R, x ≠ a: |x − a|² = 2(R² − x·a), so ∂ₙ ln|x − a| = (x − a)·x / (R|x − a|²) = 1/(2R)
//! and the two logarithms' normal derivatives cancel: no current crosses the boundary elsewhere.
//! Near a, u ≈ −ln ρ/(πσt), and the half circle of radius ρ carries σt·(πρ)·1/(πσtρ) = 1 A.
//! u(0) = 0 since |a| = |b| = R.
//!
//! **Complete electrode model** (Somersalo, Cheney and Isaacson 1992). On electrode l, the arc
//! e_l = {|θ − θ_l| ≤ α}, α = w/(2R): u + zσ∂ₙu = U_l and ∫_{e_l} σt ∂ₙu ds = I_l; elsewhere
//! σ∂ₙu = 0. Multiplying by a test pair (v, V) gives, for all (v, V),
//!
//!   σt ∫ ∇u·∇v dx + Σ_l (t/z) ∫_{e_l} (u − U_l)(v − V_l) ds = Σ_l I_l V_l.
//!
//! Galerkin on harmonic u = Σ_{n=1}^N (a_n cos nθ + b_n sin nθ)(r/R)ⁿ (zero boundary mean; the
//! common constant of u and U is fixed afterwards by Σ U_l = 0, which Σ I_l = 0 allows). The
//! Dirichlet-to-Neumann energy is ∫ ∇φ_m·∇φ_n dx = πn δ_mn for modes of one parity, 0 across.
//! With ds = R dθ and the arc integrals
//!
//!   C_l(k) = ∫_{e_l} cos kθ dθ = 2 cos(kθ_l) sin(kα)/k  (2α at k = 0),
//!   S_l(k) = ∫_{e_l} sin kθ dθ = 2 sin(kθ_l) sin(kα)/k  (odd in k),
//!
//! cos·cos = ½[C(m − n) + C(m + n)], sin·sin = ½[C(m − n) − C(m + n)],
//! cos mθ·sin nθ = ½[S(n + m) + S(n − m)]. The symmetric positive definite system of size 2N + L is
//!
//!   [σtπn δ_mn + (tR/z)·Σ_l mass, −(tR/z)·(C_l(n), S_l(n)); ·, (tw/z) δ_lj] · (a, b, U) = (0, 0, I),
//!
//! solved densely by Cholesky (O(N³): N = 800 takes ~0.06 s, N = 3200 ~1.5 s). The current
//! density jumps at the electrode edges, so convergence is algebraic. Observed for L = 16,
//! R = σ = t = 1, w = 0.1 m, z = 0.01 Ω·m², 1 A between adjacent electrodes: U₀ − U₁ changes by
//! 4.4e-2, 1.1e-2, 4.7e-3, 1.2e-3, 3.0e-4, 7.9e-5 V as N doubles from 50 to 3200 (≈ N⁻², limit
//! ≈ 1.98045 V); four-terminal voltages on electrodes carrying no current change ~100 times less.

use std::f64::consts::PI;

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

/// Potential (V) at `at` (m) for 1 A in at boundary angle `source_angle` and out at `sink_angle`
/// (rad) on a disk of `radius` (m), `conductivity` (S/m), `thickness` (m); 0 at the centre.
#[track_caller]
pub fn disk_point_dipole(
    radius: f64,
    conductivity: f64,
    thickness: f64,
    source_angle: f64,
    sink_angle: f64,
    at: [f64; 2],
) -> f64 {
    assert!(radius > 0.0 && conductivity > 0.0 && thickness > 0.0, "radius, conductivity, thickness must be > 0");
    let dist = |angle: f64| (at[0] - radius * angle.cos()).hypot(at[1] - radius * angle.sin());
    (dist(sink_angle) / dist(source_angle)).ln() / (PI * conductivity * thickness)
}

/// The complete electrode model on a disk, solved by a Fourier series; SI units throughout.
#[derive(Debug, Clone, PartialEq)]
pub struct DiskCem {
    /// Disk radius, in m.
    pub radius: f64,
    /// Conductivity of the sheet, in S/m.
    pub conductivity: f64,
    /// Sheet thickness, in m.
    pub thickness: f64,
    /// Electrode centre angles, in rad, counter-clockwise from +x.
    pub centres: Vec<f64>,
    /// Electrode arc length, in m (the same for all electrodes).
    pub width: f64,
    /// Contact impedance of every electrode, in Ω·m².
    pub contact_impedance: f64,
}

/// One unknown of the Galerkin system: a cos or sin mode n ≥ 1, or an electrode voltage.
#[derive(Clone, Copy)]
enum Unknown {
    Cos(usize),
    Sin(usize),
    Electrode(usize),
}

impl DiskCem {
    /// Electrode voltages U_l (V) for the electrode currents `current` (A, summing to 0), with
    /// Σ U_l = 0, using `modes` Fourier modes.
    #[track_caller]
    pub fn electrode_voltages(&self, current: &[f64], modes: usize) -> Vec<f64> {
        self.electrode_voltages_many(&[current], modes).pop().unwrap_or_default()
    }

    /// [`DiskCem::electrode_voltages`] for several current patterns, with one factorisation.
    #[track_caller]
    pub fn electrode_voltages_many(&self, currents: &[&[f64]], modes: usize) -> Vec<Vec<f64>> {
        let (r, t, z, l_count) = (self.radius, self.thickness, self.contact_impedance, self.centres.len());
        for current in currents {
            assert_eq!(current.len(), l_count, "one current per electrode");
            let total: f64 = current.iter().map(|i| i.abs()).sum();
            assert!(current.iter().sum::<f64>().abs() <= 1e-9 * total, "currents must sum to 0");
        }
        assert!(r > 0.0 && self.conductivity > 0.0 && t > 0.0 && z > 0.0, "parameters must be > 0");
        let alpha = self.width / (2.0 * r);
        assert!(alpha > 0.0, "electrode width must be > 0");
        for (i, &a) in self.centres.iter().enumerate() {
            for &b in &self.centres[i + 1..] {
                let gap = (a - b).rem_euclid(2.0 * PI);
                assert!(gap.min(2.0 * PI - gap) >= 2.0 * alpha, "electrodes overlap");
            }
        }

        // Arc integrals (C_l(k), S_l(k)) for k = 0..=modes per electrode, and sums up to 2·modes.
        let arc = |centre: f64, k: usize| match k {
            0 => (2.0 * alpha, 0.0),
            _ => {
                let s = 2.0 * (k as f64 * alpha).sin() / k as f64;
                (s * (k as f64 * centre).cos(), s * (k as f64 * centre).sin())
            }
        };
        let per: Vec<Vec<(f64, f64)>> =
            self.centres.iter().map(|&c| (0..=modes).map(|k| arc(c, k)).collect()).collect();
        let sums: Vec<(f64, f64)> = (0..=2 * modes)
            .map(|k| self.centres.iter().map(|&c| arc(c, k)).fold((0.0, 0.0), |s, a| (s.0 + a.0, s.1 + a.1)))
            .collect();
        let csum = |k: usize| sums[k].0;
        let ssum = |k: isize| k.signum() as f64 * sums[k.unsigned_abs()].1;

        let sheet = self.conductivity * t; // S
        let g = t * r / z; // S: the contact term per unit angle
        let kind = |i: usize| match i {
            _ if i < modes => Unknown::Cos(i + 1),
            _ if i < 2 * modes => Unknown::Sin(i - modes + 1),
            _ => Unknown::Electrode(i - 2 * modes),
        };
        let dtn = |m: usize, n: usize| if m == n { sheet * PI * n as f64 } else { 0.0 };
        let entry = |i: usize, j: usize| match (kind(i), kind(j)) {
            (Unknown::Cos(m), Unknown::Cos(n)) => dtn(m, n) + 0.5 * g * (csum(m.abs_diff(n)) + csum(m + n)),
            (Unknown::Sin(m), Unknown::Sin(n)) => dtn(m, n) + 0.5 * g * (csum(m.abs_diff(n)) - csum(m + n)),
            (Unknown::Cos(m), Unknown::Sin(n)) | (Unknown::Sin(n), Unknown::Cos(m)) => {
                0.5 * g * (ssum((n + m) as isize) + ssum(n as isize - m as isize))
            }
            (Unknown::Cos(n), Unknown::Electrode(l)) | (Unknown::Electrode(l), Unknown::Cos(n)) => -g * per[l][n].0,
            (Unknown::Sin(n), Unknown::Electrode(l)) | (Unknown::Electrode(l), Unknown::Sin(n)) => -g * per[l][n].1,
            (Unknown::Electrode(l), Unknown::Electrode(m)) => {
                if l == m {
                    t * self.width / z
                } else {
                    0.0
                }
            }
        };
        let size = 2 * modes + l_count;
        let a = Mat::from_fn(size, size, entry);
        let rhs =
            Mat::from_fn(size, currents.len(), |i, k| if i >= 2 * modes { currents[k][i - 2 * modes] } else { 0.0 });
        let x = match a.llt(Side::Lower) {
            Ok(llt) => llt.solve(&rhs),
            Err(_) => a.partial_piv_lu().solve(&rhs), // not reached for valid input: A is SPD
        };
        (0..currents.len())
            .map(|k| {
                let mean = (0..l_count).map(|l| x[(2 * modes + l, k)]).sum::<f64>() / l_count as f64;
                (0..l_count).map(|l| x[(2 * modes + l, k)] - mean).collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const L: usize = 16;

    fn ring(width: f64, contact_impedance: f64) -> DiskCem {
        let centres = (0..L).map(|l| 2.0 * PI * l as f64 / L as f64).collect();
        DiskCem { radius: 1.0, conductivity: 1.0, thickness: 1.0, centres, width, contact_impedance }
    }

    fn pair(source: usize, sink: usize) -> Vec<f64> {
        (0..L).map(|l| f64::from(u8::from(l == source)) - f64::from(u8::from(l == sink))).collect()
    }

    fn rel(a: &[f64], b: &[f64]) -> f64 {
        let d = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        d / b.iter().map(|y| y.abs()).fold(0.0, f64::max)
    }

    fn dipole(at: [f64; 2]) -> f64 {
        disk_point_dipole(1.0, 1.0, 1.0, 0.3, 2.0, at)
    }

    #[test]
    fn dipole_has_no_normal_current_off_the_electrodes() {
        let h = 1e-5;
        for theta in [0.0, 1.0, 1.5, 3.0, 4.5, 6.0] {
            let (c, s) = (f64::cos(theta), f64::sin(theta));
            let du = (dipole([(1.0 + h) * c, (1.0 + h) * s]) - dipole([(1.0 - h) * c, (1.0 - h) * s])) / (2.0 * h);
            assert!(du.abs() < 1e-8, "θ = {theta}: ∂u/∂r = {du}");
        }
    }

    #[test]
    fn dipole_carries_one_ampere() {
        // Current through the part inside the disk of a circle of radius ε round each end
        // (Simpson's rule on the exact gradient), with σt = 2 so the scaling is checked too.
        let (sigma, t, eps): (f64, f64, f64) = (0.5, 4.0, 0.05);
        let (a, b) = ([0.3f64.cos(), 0.3f64.sin()], [2.0f64.cos(), 2.0f64.sin()]);
        let grad = |x: [f64; 2]| {
            let term = |p: [f64; 2], sign: f64| {
                let d = [x[0] - p[0], x[1] - p[1]];
                let q = d[0] * d[0] + d[1] * d[1];
                [sign * d[0] / q, sign * d[1] / q]
            };
            let (gb, ga) = (term(b, 1.0), term(a, -1.0));
            [(gb[0] + ga[0]) / (PI * sigma * t), (gb[1] + ga[1]) / (PI * sigma * t)]
        };
        for (p, theta, expected) in [(a, 0.3f64, 1.0), (b, 2.0, -1.0)] {
            let half = (-eps / 2.0).acos(); // the arc inside: |φ − θ| ∈ (half, π]
            let n = 400;
            let step = 2.0 * (PI - half) / n as f64;
            let flux: f64 = (0..=n)
                .map(|i| {
                    let phi = theta + half + i as f64 * step;
                    let nu = [phi.cos(), phi.sin()];
                    let g = grad([p[0] + eps * nu[0], p[1] + eps * nu[1]]);
                    let w = if i == 0 || i == n {
                        1.0
                    } else if i % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    -w * sigma * t * (g[0] * nu[0] + g[1] * nu[1]) * eps * step / 3.0
                })
                .sum();
            assert!((flux - expected).abs() < 1e-9, "flux {flux}");
        }
    }

    #[test]
    fn dipole_is_odd_under_the_reflection_swapping_source_and_sink() {
        let mirror: f64 = (0.3 + 2.0) / 2.0; // the perpendicular bisector of a and b passes the origin
        let (c, s) = ((2.0 * mirror).cos(), (2.0 * mirror).sin());
        assert_eq!(dipole([0.0, 0.0]), 0.0);
        for x in [[0.2, 0.1], [-0.5, 0.7], [0.9, -0.3], [1.0, 0.0]] {
            let reflected = [c * x[0] + s * x[1], s * x[0] - c * x[1]];
            assert!((dipole(reflected) + dipole(x)).abs() < 1e-12, "{x:?}");
        }
    }

    #[test]
    fn cem_is_reciprocal() {
        let cem = ring(0.1, 0.01);
        let i: Vec<f64> = (0..L).map(|l| (l as f64 * 0.7).sin()).collect();
        let mean = i.iter().sum::<f64>() / L as f64;
        let i: Vec<f64> = i.iter().map(|x| x - mean).collect();
        let j = pair(2, 11);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let (ji, ij) = (dot(&j, &cem.electrode_voltages(&i, 200)), dot(&i, &cem.electrode_voltages(&j, 200)));
        assert!((ji - ij).abs() <= 1e-10 * ji.abs(), "{ji} vs {ij}");
        assert!(cem.electrode_voltages(&i, 200).iter().sum::<f64>().abs() < 1e-12);
    }

    #[test]
    fn cem_scales_as_one_over_conductivity_times_thickness() {
        let cem = ring(0.1, 0.01);
        let v = cem.electrode_voltages(&pair(0, 4), 100);
        let thick = DiskCem { thickness: 2.0, ..cem.clone() };
        let half: Vec<f64> = v.iter().map(|x| x / 2.0).collect();
        assert!(rel(&thick.electrode_voltages(&pair(0, 4), 100), &half) < 1e-12);
        let k = 3.0;
        let scaled = DiskCem { conductivity: k, contact_impedance: 0.01 / k, ..cem };
        let third: Vec<f64> = v.iter().map(|x| x / k).collect();
        assert!(rel(&scaled.electrode_voltages(&pair(0, 4), 100), &third) < 1e-12);
    }

    #[test]
    fn cem_converges_in_modes() {
        let cem = ring(0.1, 0.01);
        let v: Vec<f64> = [100, 200, 400, 800]
            .iter()
            .map(|&n| {
                let u = cem.electrode_voltages(&pair(0, 1), n);
                u[0] - u[1]
            })
            .collect();
        let d: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        // Observed: about N⁻², the change per doubling shrinking by 3.8, 2.5, 3.8 here.
        assert!(v.windows(2).all(|w| w[1] > w[0]), "{v:?}");
        assert!(d.windows(2).all(|w| w[1] < 0.5 * w[0]), "{v:?}, changes {d:?}");
        assert!(d[2] < 1e-3 * v[3].abs(), "{v:?}");
    }

    #[test]
    fn small_electrodes_approach_the_point_dipole() {
        let cem = ring(1e-3, 1e-6);
        let u = cem.electrode_voltages(&pair(0, 1), 800);
        let angle = |l: usize| 2.0 * PI * l as f64 / L as f64;
        let point = |l: usize| disk_point_dipole(1.0, 1.0, 1.0, 0.0, angle(1), [angle(l).cos(), angle(l).sin()]);
        // Observed relative error per pair: 2e-5 next to the driven pair, 1e-6 opposite it (N = 800);
        // it levels off near 6e-6 as N grows, the O((w/d)²) effect of the finite electrodes.
        for l in 2..L - 1 {
            let (cem_diff, point_diff) = (u[l] - u[l + 1], point(l) - point(l + 1));
            let err = (cem_diff - point_diff).abs() / point_diff.abs();
            assert!(err < 1e-4, "pair {l}-{}: {cem_diff} vs {point_diff}, relative error {err}", l + 1);
        }
    }
}
