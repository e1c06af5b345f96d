//! Presses found in Δv itself, one after another, each tested against the measured noise: the
//! image is a blurred, regularised view in which a weak press beside a strong one, or the side
//! lobe of a strong one, cannot be told apart; Δv against the model's own responses can.
//!
//! With Δv and the responses whitened by the noise (each channel divided by its standard
//! deviation, [`PressModel::whitened`]), gᵀΔv/|g| is, for a press at any grid point, a z-score
//! that noise alone draws from N(0, 1) (the matched filter, or generalised likelihood-ratio
//! test, of one press). [`PressModel::detect_into`] takes the grid point with the largest z over
//! the whole sheet; if it passes the threshold, a press is fitted there, and then every press
//! found so far is placed again in turn, anywhere on the sheet, against Δv less the others'
//! responses (a first pick that fell between two presses moves onto one once the other is
//! found; then twice more near where each is); then the same on Δv less all their responses,
//! away from the presses found (two
//! indenter radii: what is left next to a strong press is the linear model's error, not another
//! press), until the largest z left fails, or 16 presses. A press is kept when its own z
//! (against Δv less the others') passes too, and its drop is at least [`MIN_DROP`]. With the
//! model's exact responses ([`super::ExactPresses`]), the presses are then fitted together with
//! them and the set corrected by what that fit shows (`joint.rs`).
//!
//! The threshold is for the largest of many correlated z over the grid, so, as for images
//! ([`crate::noise`]), it comes from the model's own noise: [`PressDetection::new`] draws
//! [`CALIBRATION_SAMPLES`] whitened noise frames, takes the 90th percentile of their largest z
//! and extends the tail as a 2-D Gaussian field's, c·z·e^(−z²/2), to the false-alarm rate asked.
//!
//! Not for: presses closer together than about two indenter radii (their responses are then
//! nearly the same vector), or a press much larger than the indenter.

use crate::SeededRng;
use rand::SeedableRng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};

use super::exact::ExactPresses;
use super::scan::Scan;
use super::tabulated::TabulatedPresses;
use super::{PressFit, PressModel, PressScratch, TableUse, SWEEPS};
use crate::inverse::InverseError;
use crate::noise::{threshold_of, CALIBRATION_SAMPLES};

/// The most presses found in one frame.
pub const MAX_PRESSES: usize = 16;

/// The smallest drop a press found must have (a fraction of the background; 0.3 N on the paper's
/// gel): what the linear responses leave of a strong press, or of several, can pass the noise
/// test where the noise is low, and is fitted as weak presses beside them (in the study's noise
/// sweep, half of such false presses had a drop under 0.02).
pub const MIN_DROP: f64 = 0.05;

/// Response-grid points between the search's scan points each way (a scan step of half the
/// indenter's radius).
const SCAN_STRIDE: usize = 2;

/// The exact fit of presses found: their exact responses, Δv (V) and each channel's weight
/// (1/std, 0 for a channel not used).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Exact<'a> {
    pub(crate) presses: &'a ExactPresses,
    /// One press's response tabulated, if the model fits on it: fits at the indenter's radius
    /// read it (with `start` too, [`TableUse::Auto`]: while the frame is on the table).
    pub(crate) table: Option<&'a TabulatedPresses>,
    /// One press's response tabulated, if the model starts exact fits from it.
    pub(crate) start: Option<&'a TabulatedPresses>,
    pub(crate) dv: &'a [f64],
    pub(crate) weights: &'a [f64],
}

/// A press model whitened by the measured noise, with the z a press must reach.
#[derive(Debug, Clone, PartialEq)]
pub struct PressDetection {
    pub(super) model: PressModel,
    pub(super) scan: Scan,
    /// Per channel, the noise's standard deviation (the unit of Δv; ∞ for a channel not used).
    std: Vec<f64>,
    /// Per channel, 1/std (0 for a channel not used): the weights of the exact fit.
    pub(super) weights: Vec<f64>,
    pub(super) threshold: f64,
    false_alarm_rate: f64,
}

impl PressDetection {
    /// Detection with `model` under channel noise of standard deviation `std` (one per
    /// measurement, in Δv's unit; not positive or not finite: the channel is not used), each
    /// estimated with `dof` degrees of freedom (frames less one; `f64::INFINITY` for a noise
    /// known exactly), at `false_alarm_rate` false presses per frame without one, in (0, 0.5].
    ///
    /// A standard deviation estimated from few frames is off by a factor that stays for every
    /// frame, and a press near an electrode rests on a few channels: so the noise frames the
    /// threshold is taken from are drawn with each channel's estimate off as a χ² of `dof` says
    /// (the whitened noise of a channel is N(0, 1)·√(ν/χ²_ν)), and the threshold holds on average
    /// over what the estimate could have been.
    pub fn new(
        model: &PressModel,
        std: &[f64],
        dof: f64,
        false_alarm_rate: f64,
    ) -> Result<PressDetection, InverseError> {
        if std.len() != model.measurements() {
            return Err(InverseError::FrameLength { expected: model.measurements(), got: std.len() });
        }
        assert!(false_alarm_rate > 0.0 && false_alarm_rate <= 0.5, "a false-alarm rate in (0, 0.5]");
        let std: Vec<f64> = std.iter().map(|s| if *s > 0.0 && s.is_finite() { *s } else { f64::INFINITY }).collect();
        let model = model.whitened(&std);
        let scan = Scan::with_stride(&model, SCAN_STRIDE);
        let mut rng = SeededRng::seed_from_u64(0x0d37_ec75);
        let (mut noise, mut correlations) = (vec![0.0; model.measurements()], Vec::new());
        let misestimate = ChiSquared::new(dof).ok().filter(|_| dof.is_finite() && dof > 0.0);
        let maxima: Vec<f64> = (0..CALIBRATION_SAMPLES)
            .map(|_| {
                for n in noise.iter_mut() {
                    let scale = misestimate.map_or(1.0, |chi| (dof / chi.sample(&mut rng)).sqrt());
                    let normal: f64 = StandardNormal.sample(&mut rng);
                    *n = scale * normal;
                }
                model.best_point(&scan, &noise, &[], &mut correlations).map_or(0.0, |(_, z)| z)
            })
            .collect();
        let (_, threshold) = threshold_of(&maxima, false_alarm_rate);
        let weights = std.iter().map(|s| 1.0 / s).collect();
        Ok(PressDetection { model, scan, std, weights, threshold, false_alarm_rate })
    }

    /// The z a press must reach (dimensionless).
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// Radius of the indenter the model fits, in m.
    pub fn radius(&self) -> f64 {
        self.model.radius()
    }

    /// False presses per frame without one that the threshold allows.
    pub fn false_alarm_rate(&self) -> f64 {
        self.false_alarm_rate
    }

    /// The presses in `dv` (Δv in protocol order, in the unit of the noise given), strongest
    /// first, into `out` (cleared); channels not used are ignored, whatever they hold.
    /// `whitened` is a buffer of Δv's length. Allocates nothing once the buffers have grown.
    pub fn detect_into(
        &self,
        dv: &[f64],
        whitened: &mut Vec<f64>,
        scratch: &mut PressScratch,
        out: &mut Vec<PressFit>,
    ) -> Result<(), InverseError> {
        out.clear();
        self.whiten_into(dv, whitened)?;
        self.model.detect_into(&self.scan, whitened, self.threshold, self.exact(dv), scratch, out)
    }
}

impl PressDetection {
    /// `dv` divided by each channel's noise into `whitened` (0 on a channel not used); an
    /// error if its length is not the model's.
    pub(super) fn whiten_into(&self, dv: &[f64], whitened: &mut Vec<f64>) -> Result<(), InverseError> {
        if dv.len() != self.std.len() {
            return Err(InverseError::FrameLength { expected: self.std.len(), got: dv.len() });
        }
        whitened.clear();
        whitened.extend(dv.iter().zip(&self.std).map(|(d, s)| if s.is_finite() { d / s } else { 0.0 }));
        Ok(())
    }

    /// The exact fit of Δv `dv` (V), if the model has exact responses.
    pub(super) fn exact<'a>(&'a self, dv: &'a [f64]) -> Option<Exact<'a>> {
        self.model.exact.as_deref().map(|presses| Exact {
            presses,
            table: self.model.tabulated.as_deref().filter(|_| self.model.table_use != TableUse::Start),
            start: self.model.tabulated.as_deref().filter(|_| self.model.table_use != TableUse::Fit),
            dv,
            weights: &self.weights,
        })
    }
}

impl PressModel {
    /// The same model for Δv whitened by the noise: each channel's responses divided by its
    /// standard deviation `std` (∞ for a channel not used: its responses become 0).
    pub fn whitened(&self, std: &[f64]) -> PressModel {
        assert_eq!(std.len(), self.measurements, "one standard deviation per measurement");
        let mut whitened = self.clone();
        for g in whitened.responses.chunks_exact_mut(self.measurements) {
            g.iter_mut().zip(std).for_each(|(g, s)| *g /= s);
        }
        whitened.norms =
            whitened.responses.chunks_exact(self.measurements).map(|g| g.iter().map(|x| x * x).sum()).collect();
        whitened
    }

    /// Presses found one after another in `dv`, each starting where the largest z is left and
    /// all placed again in turn, until the largest z left is under `threshold` (see the
    /// [module doc](self)); those whose own z passes, strongest (largest drop) first, into `out`.
    /// For whitened Δv and model. Allocates nothing once `scratch` and `out` have grown.
    pub(crate) fn detect_into(
        &self,
        scan: &Scan,
        dv: &[f64],
        threshold: f64,
        exact: Option<Exact<'_>>,
        scratch: &mut PressScratch,
        out: &mut Vec<PressFit>,
    ) -> Result<(), InverseError> {
        out.clear();
        let m = self.measurements;
        if dv.len() != m {
            return Err(InverseError::FrameLength { expected: m, got: dv.len() });
        }
        if dv.iter().any(|v| !v.is_finite()) {
            return Ok(());
        }
        let PressScratch { residual, response, responses, centres, correlations, .. } = scratch;
        let mut found: [Option<PressFit>; MAX_PRESSES] = [None; MAX_PRESSES];
        let mut count = 0;
        responses.clear();
        responses.resize(MAX_PRESSES * m, 0.0);
        residual.resize(m, 0.0);
        response.resize(m, 0.0);
        // Δv less every press's response but `skip`'s, into `residual`; the others' centres.
        let rest = |skip: usize,
                    count: usize,
                    residual: &mut Vec<f64>,
                    centres: &mut Vec<[f64; 2]>,
                    responses: &[f64],
                    found: &[Option<PressFit>]| {
            residual.copy_from_slice(dv);
            centres.clear();
            for k in (0..count).filter(|&k| k != skip) {
                residual.iter_mut().zip(&responses[k * m..(k + 1) * m]).for_each(|(r, g)| *r -= g);
                centres.extend(found[k].map(|f| f.centre));
            }
        };
        while count < MAX_PRESSES {
            rest(count, count, residual, centres, responses, &found);
            let Some((j, z)) = self.best_point(scan, residual, centres, correlations) else { break };
            if z < threshold {
                break;
            }
            // The new press, then each press placed again on Δv less the others (a greedy
            // pick between two presses moves to one of them once the other is found).
            let window = 2.0 * self.grid.spacing;
            let Some(new) = self.fit_one(residual, self.grid.point(j), window, response) else { break };
            found[count] = Some(new);
            responses[count * m..(count + 1) * m]
                .iter_mut()
                .zip(response.iter())
                .for_each(|(r, g)| *r = new.contrast * g);
            count += 1;
            for sweep in 0..SWEEPS {
                for i in 0..count {
                    // A first press placed anywhere is where it was just picked and fitted.
                    if sweep == 0 && count == 1 {
                        continue;
                    }
                    rest(i, count, residual, centres, responses, &found);
                    // Anywhere on the sheet first, then near where it is.
                    let start = match (sweep, found[i]) {
                        (0, _) | (_, None) => match self.best_point(scan, residual, centres, correlations) {
                            Some((j, _)) => self.grid.point(j),
                            None => continue,
                        },
                        (_, Some(fit)) => fit.centre,
                    };
                    if let Some(fit) = self.fit_one(residual, start, window, response) {
                        found[i] = Some(fit);
                        let g = &mut responses[i * m..(i + 1) * m];
                        g.iter_mut().zip(response.iter()).for_each(|(r, g)| *r = fit.contrast * g);
                    }
                }
            }
        }
        match exact {
            // Then all fitted together with their exact responses, the set corrected by them.
            Some(exact) => {
                out.extend(found[..count].iter().flatten());
                self.fit_jointly(scan, dv, threshold, exact, out, scratch)?;
            }
            None => out.extend(found[..count].iter().flatten().filter(|f| f.z >= threshold && f.drop >= MIN_DROP)),
        }
        out.sort_unstable_by(|a, b| b.drop.total_cmp(&a.drop));
        Ok(())
    }
}
