//! Calibration learned from labelled presses: a model from a frame (or Δv) to where the press
//! is and how hard, for skins whose outline, electrodes, gains and gel nobody knows exactly.
//!
//! The channels are z-scored over the training presses and the dead ones (constant,
//! saturated, not finite) dropped ([`Standardiser`]). Then, side by side:
//! - k-nearest neighbours ([`RegressorKind::Knn`]): the floor;
//! - Gaussian-process regression ([`RegressorKind::GaussianProcess`]): kernel ridge whose length
//!   scale and noise come from the log marginal likelihood, with an uncertainty per answer;
//!
//! each on the channels as they are, on their shape, or on the press fitted to Δv on the sensor
//! as specified ([`Features`]; [`PressFeatures`], given a [`NominalSensor`]): physics features
//! that are nearly the label already, so that 100 presses teach what the spec got wrong.
//!
//! and, on press features, the physics alone ([`RegressorKind::Curve`]: the fitted centre, and
//! the force its drop gives on one calibration curve) or the physics with a Gaussian process on
//! what it gets wrong ([`RegressorKind::CurveResidual`]).
//!
//! [`choose`] picks one by k-fold cross-validation on the training presses alone; [`baseline`]
//! scores the plain kernel ridge a user would try first on the same folds, to say whether the
//! choice beats it.
//!
//! ```
//! use eitskin::learn::{choose, train, LabelledPress, Method, PredictScratch};
//! // A toy "sensor": three channels that vary smoothly with the press's position (m).
//! let frame = |x: f64, y: f64| vec![x + 0.2 * y * y, y - 0.1 * x, x * y];
//! let presses: Vec<LabelledPress> = (0..81)
//!     .map(|i| {
//!         let (x, y) = ((i % 9) as f64 / 8.0 - 0.5, (i / 9) as f64 / 8.0 - 0.5);
//!         LabelledPress { inputs: frame(x, y), position: [x, y], force: None, depth: None }
//!     })
//!     .collect();
//! // Every candidate's cross-validated error; here the Gaussian process on raw channels.
//! let (_best, scores) = choose(&presses, &Method::candidates(false), 5, None, &mut |_, _, _| {})?;
//! assert_eq!(scores.len(), Method::candidates(false).len());
//! let model = train(&presses, Method::from_name("gp").unwrap(), None)?;
//! let answer = model.predict(&frame(0.1, -0.2), &mut PredictScratch::default()).unwrap();
//! assert!((answer.position[0] - 0.1).abs() < 0.01 && (answer.position[1] + 0.2).abs() < 0.01);
//! assert!(answer.position_std.is_some());
//! # Ok::<(), eitskin::learn::LearnError>(())
//! ```

mod curve;
mod gp;
mod kernel_ridge;
mod knn;
mod press_features;
mod standardise;

pub use curve::PressCurves;
pub use gp::{GaussianProcess, GpScratch, LENGTH_SCALES, LINEAR_WEIGHTS, NOISE_VARIANCES};
pub use kernel_ridge::{baseline, evaluate_baseline, Baseline, KernelRidge};
pub use knn::Knn;
pub use press_features::{FeatureScratch, NominalSensor, PressFeatures, NOISE_FLOOR};
pub use standardise::{Standardiser, DEAD_SPREAD};

use thiserror::Error;

use crate::press_fit::PressFit;

/// What is wrong with a training set or a frame.
#[derive(Debug, PartialEq, Error)]
pub enum LearnError {
    /// Too few presses to train on (or to split into folds).
    #[error("{got} labelled presses are too few: at least {needed} are needed")]
    TooFewPresses {
        /// Presses given.
        got: usize,
        /// Presses needed.
        needed: usize,
    },
    /// A press has another number of channels than the first.
    #[error("press {press} has {got} channels, the first press {expected}")]
    Channels {
        /// 1-based press.
        press: usize,
        /// Channels of the first press.
        expected: usize,
        /// Channels of this one.
        got: usize,
    },
    /// Some presses have a force and some do not.
    #[error("press {press} has no force while others have one: label every press's force or none")]
    MixedForces {
        /// 1-based press.
        press: usize,
    },
    /// Some presses have a depth and some do not.
    #[error("press {press} has no depth while others have one: label every press's depth or none")]
    MixedDepths {
        /// 1-based press.
        press: usize,
    },
    /// A label is not a finite number.
    #[error("press {press}'s {label} is {value}: every label must be a finite number")]
    LabelNotFinite {
        /// 1-based press.
        press: usize,
        /// Which label: "x", "y", "force" or "depth".
        label: &'static str,
        /// Its value.
        value: f64,
    },
    /// Every press is labelled at one place: nothing tells positions apart.
    #[error("every one of the {presses} presses is labelled at ({x} m, {y} m): a model of position needs presses at two places or more")]
    OnePlace {
        /// Presses given.
        presses: usize,
        /// The one place's x, in m.
        x: f64,
        /// Its y, in m.
        y: f64,
    },
    /// Presses whose inputs are of another size than the training presses'.
    #[error("these presses' inputs are typically {given:.4e} (root mean square, the median press), {ratio:.3} times the {trained:.4e} of the presses the model learned from: a press changes a frame by percents, so these are in another unit or gain, or raw frames given to a model of Δv (give the reference the model's presses were taken against)")]
    Scale {
        /// Their size against the training presses'.
        ratio: f64,
        /// Their typical size, in the inputs' unit.
        given: f64,
        /// The training presses' typical size.
        trained: f64,
    },
    /// Every channel is dead.
    #[error("every channel is constant or not finite over the training presses: nothing to learn from")]
    NoChannels,
    /// The process could not be fitted (its kernel matrix not positive definite at any grid point).
    #[error("the Gaussian process could not be fitted to these presses")]
    NotFitted,
    /// Press features were asked for without the sensor as specified.
    #[error("press features need the sensor's spec (its press model), and none was given")]
    NoSensor,
    /// Too few presses' Δv match a press on the sensor's model for press features.
    #[error("only {like} of {given} presses' Δv look like a press on the sensor as specified (the others zero, not finite, or unlike any press): too few for press features; learn from the channels")]
    FewLikePresses {
        /// Presses whose Δv looks like a press.
        like: usize,
        /// Presses given.
        given: usize,
    },
    /// The spec does not make a sensor.
    #[error("the sensor spec does not make a sensor")]
    Spec(#[from] crate::SpecError),
    /// k-nearest neighbours with k larger than the presses it would learn from (every answer
    /// would be their mean).
    #[error("knn-{k} needs at least {k} presses to learn from, and has {presses}: give a smaller k")]
    TooFewForNeighbours {
        /// Neighbours asked for.
        k: usize,
        /// Presses it would learn from.
        presses: usize,
    },
    /// A method that reads the fitted press was given other features.
    #[error("{method} reads the press fitted on the sensor as specified: give it press features")]
    NotPressFeatures {
        /// The method's name.
        method: String,
    },
    /// The physical curve could not be fitted to the presses' labels.
    #[error("no curve of the label on the fitted press's drop")]
    Curve(#[from] crate::calibration::CalibrationError),
    /// The sensor as specified could not be solved.
    #[error("the sensor as specified could not be solved")]
    Forward(#[from] crate::ForwardError),
    /// Its press features could not be computed.
    #[error("the sensor's press features could not be computed")]
    Inverse(#[from] crate::InverseError),
    /// Its press model could not be built.
    #[error("the sensor's press model could not be built")]
    PressModel(#[from] crate::press_fit::PressModelError),
}

/// One press with its label: the frame's values (or Δv), its position in m, its force in N.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledPress {
    /// The channels, in protocol order.
    pub inputs: Vec<f64>,
    /// Where it was pressed, in m.
    pub position: [f64; 2],
    /// How hard, in N, when labelled.
    pub force: Option<f64>,
    /// How deep the indenter went, in m, when labelled (a robot that sets depth, not force).
    pub depth: Option<f64>,
}

/// A way to learn: a regressor on one kind of feature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Method {
    /// The regressor.
    pub regressor: RegressorKind,
    /// The features it sees.
    pub features: Features,
}

/// The regressors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegressorKind {
    /// The mean of the k nearest training presses in z-scored feature space.
    Knn {
        /// Neighbours, ≥ 1.
        k: usize,
    },
    /// Gaussian-process regression on z-scored features.
    GaussianProcess,
    /// The physics alone ([`PressCurves`]): the fitted press's centre, and the force (and
    /// depth) its drop gives on one curve fitted to the training presses. Press features only.
    Curve,
    /// [`RegressorKind::Curve`] plus a Gaussian process on what it gets wrong: the physics
    /// where presses are few, corrected where they teach. Press features only.
    CurveResidual,
}

impl RegressorKind {
    /// Whether it reads the fitted press itself (and so needs press features).
    pub const fn reads_press(self) -> bool {
        matches!(self, RegressorKind::Curve | RegressorKind::CurveResidual)
    }
}

/// What the regressor sees of a press's channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Features {
    /// The channels as they are.
    Raw,
    /// The channels' direction (divided by their Euclidean norm) and the norm's logarithm: where
    /// a press is shows in the pattern, how hard mostly in the size, so a harder press does not
    /// look like a press elsewhere.
    Shape,
    /// The press fitted on the sensor as specified ([`PressFeatures`]): its x, y and log
    /// contrast. Needs the spec.
    Press,
}

impl Method {
    /// k-nearest neighbours on raw channels: the floor.
    pub const fn knn(k: usize) -> Method {
        Method { regressor: RegressorKind::Knn { k }, features: Features::Raw }
    }

    /// The methods [`choose`] tries: k = 1, 3, 5, 10 neighbours and the Gaussian process, each on
    /// raw and on shape features, and on press features when `sensor` (the spec is known),
    /// with the physical curve alone and with its learned residual.
    pub fn candidates(sensor: bool) -> Vec<Method> {
        let regressors =
            [1, 3, 5, 10].map(|k| RegressorKind::Knn { k }).into_iter().chain([RegressorKind::GaussianProcess]);
        let features: &[Features] =
            if sensor { &[Features::Raw, Features::Shape, Features::Press] } else { &[Features::Raw, Features::Shape] };
        let physics = [RegressorKind::Curve, RegressorKind::CurveResidual]
            .into_iter()
            .filter(|_| sensor)
            .map(|regressor| Method { regressor, features: Features::Press });
        regressors
            .flat_map(|regressor| features.iter().map(move |&features| Method { regressor, features }))
            .chain(physics)
            .collect()
    }

    /// Its name, as files and reports write it ("knn-5", "gp", "gp-shape", "gp-press",
    /// "curve-press", "gp-curve-press").
    pub fn name(&self) -> String {
        let base = match self.regressor {
            RegressorKind::Knn { k } => format!("knn-{k}"),
            RegressorKind::GaussianProcess => "gp".into(),
            RegressorKind::Curve => "curve".into(),
            RegressorKind::CurveResidual => "gp-curve".into(),
        };
        match self.features {
            Features::Raw => base,
            Features::Shape => format!("{base}-shape"),
            Features::Press => format!("{base}-press"),
        }
    }

    /// The method of a name from [`Method::name`].
    pub fn from_name(name: &str) -> Option<Method> {
        let (base, features) = match (name.strip_suffix("-shape"), name.strip_suffix("-press")) {
            (Some(base), _) => (base, Features::Shape),
            (_, Some(base)) => (base, Features::Press),
            _ => (name, Features::Raw),
        };
        let regressor = if base == "gp" {
            RegressorKind::GaussianProcess
        } else if let Some(regressor) = [("curve", RegressorKind::Curve), ("gp-curve", RegressorKind::CurveResidual)]
            .into_iter()
            .find_map(|(name, regressor)| (name == base).then_some(regressor))
        {
            if features != Features::Press {
                return None;
            }
            regressor
        } else {
            let k: usize = base.strip_prefix("knn-")?.parse().ok()?;
            if k == 0 {
                return None;
            }
            RegressorKind::Knn { k }
        };
        Some(Method { regressor, features })
    }
}

impl Features {
    /// The features of `channels` into `out` (cleared first); press features are
    /// [`PressFeatures::features_into`]'s, so here the channels as they are.
    pub fn of_into(self, channels: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.extend_from_slice(channels);
        if self == Features::Shape {
            let norm = channels.iter().filter(|v| v.is_finite()).map(|v| v * v).sum::<f64>().sqrt();
            if norm > 0.0 {
                out.iter_mut().for_each(|v| *v /= norm);
            }
            out.push(norm.max(f64::MIN_POSITIVE).ln());
        }
    }
}

/// The trained regressor.
#[derive(Debug, Clone)]
pub enum Regressor {
    /// k-nearest neighbours.
    Knn(Knn),
    /// A Gaussian process.
    GaussianProcess(GaussianProcess),
    /// The physical answer, and a Gaussian process on what it gets wrong where trained with one.
    Curve {
        /// The curves of the labels on the fitted drop.
        curves: PressCurves,
        /// The process on the physical answer's error, for [`RegressorKind::CurveResidual`].
        residual: Option<GaussianProcess>,
    },
}

/// A trained model: frame → position (m), force (N) when trained with forces, uncertainty.
#[derive(Debug, Clone)]
pub struct LearnedModel {
    /// The method it was trained with.
    pub method: Method,
    /// Channel scaling and the dead channels.
    pub standardiser: Standardiser,
    /// The regressor on the used channels.
    pub regressor: Regressor,
    /// Whether it gives forces.
    pub forces: bool,
    /// Whether it gives depths.
    pub depths: bool,
    /// The fitted press, for press features.
    pub press: Option<PressFeatures>,
    /// The training presses (0-based) it left out: for press features, those whose Δv looks
    /// like no press ([`PressFeatures::unlike`]).
    pub left_out: Vec<usize>,
    /// The typical size of a training press's inputs ([`typical_size`]), in their unit: what
    /// [`LearnedModel::check_scale`] holds other presses to.
    pub input_size: f64,
}

/// One answer of a model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Where, in m.
    pub position: [f64; 2],
    /// How hard, in N, when the model was trained with forces.
    pub force: Option<f64>,
    /// The predictive standard deviation of the position (the larger of x and y), in m; only
    /// a Gaussian process gives one.
    pub position_std: Option<f64>,
    /// The predictive standard deviation of the force, in N (a Gaussian process's, or the
    /// physical curve's).
    pub force_std: Option<f64>,
    /// How deep, in m, when the model was trained with depths.
    pub depth: Option<f64>,
    /// The predictive standard deviation of the depth, in m.
    pub depth_std: Option<f64>,
}

/// Buffers for [`LearnedModel::predict`], grown on first use.
#[derive(Debug, Default)]
pub struct PredictScratch {
    features: Vec<f64>,
    press: FeatureScratch,
    z: Vec<f64>,
    nearest: Vec<(f64, usize)>,
    gp: GpScratch,
}

/// Checks the presses agree in channels and in having forces and depths; whether they have each.
fn check(presses: &[LabelledPress], needed: usize) -> Result<(bool, bool), LearnError> {
    if presses.len() < needed {
        return Err(LearnError::TooFewPresses { got: presses.len(), needed });
    }
    let expected = presses[0].inputs.len();
    let (forces, depths) = (presses[0].force.is_some(), presses[0].depth.is_some());
    for (i, p) in presses.iter().enumerate() {
        if p.inputs.len() != expected {
            return Err(LearnError::Channels { press: i + 1, expected, got: p.inputs.len() });
        }
        if p.force.is_some() != forces {
            return Err(LearnError::MixedForces { press: i + 1 });
        }
        if p.depth.is_some() != depths {
            return Err(LearnError::MixedDepths { press: i + 1 });
        }
        let labels = [("x", Some(p.position[0])), ("y", Some(p.position[1])), ("force", p.force), ("depth", p.depth)];
        if let Some((label, value)) =
            labels.into_iter().find_map(|(l, v)| Some((l, v?)).filter(|(_, v)| !v.is_finite()))
        {
            return Err(LearnError::LabelNotFinite { press: i + 1, label, value });
        }
    }
    let first = presses[0].position;
    if presses.iter().all(|p| p.position == first) {
        return Err(LearnError::OnePlace { presses: presses.len(), x: first[0], y: first[1] });
    }
    Ok((forces, depths))
}

/// The presses that repeat an earlier one exactly (every label and every input, bit for bit), as
/// (copy, the press it copies), 0-based: a press pasted twice teaches nothing new and makes
/// cross-validation test a press on itself.
pub fn copies(presses: &[LabelledPress]) -> Vec<(usize, usize)> {
    let key = |p: &LabelledPress| -> Vec<u64> {
        let labels = [p.position[0], p.position[1], p.force.unwrap_or(f64::NAN), p.depth.unwrap_or(f64::NAN)];
        labels.iter().chain(&p.inputs).map(|v| v.to_bits()).collect()
    };
    let mut first = std::collections::HashMap::new();
    let mut found = Vec::new();
    for (i, p) in presses.iter().enumerate() {
        match first.entry(key(p)) {
            std::collections::hash_map::Entry::Occupied(e) => found.push((i, *e.get())),
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(i);
            }
        }
    }
    found
}

/// Presses left out as exact copies of earlier ones ([`copies`]); says which, 1-based.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CopiesLeftOut {
    /// (copy, the press it copies), 0-based.
    pub copies: Vec<(usize, usize)>,
    /// Presses given.
    pub of: usize,
}

impl std::fmt::Display for CopiesLeftOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let named: Vec<String> = self.copies.iter().take(5).map(|(c, o)| format!("{} of {}", c + 1, o + 1)).collect();
        let more = if self.copies.len() > named.len() { ", …" } else { "" };
        write!(
            f,
            "{} of {} presses repeat an earlier one exactly (press {}{more}) and are left out: a copy teaches nothing and flatters the cross-validation",
            self.copies.len(),
            self.of,
            named.join(", ")
        )
    }
}

/// The typical size of presses' inputs: the median over presses of the root mean square of
/// each one's finite inputs; `None` where no press has a finite input.
pub fn typical_size<'a>(inputs: impl Iterator<Item = &'a [f64]>) -> Option<f64> {
    let mut sizes: Vec<f64> = inputs
        .filter_map(|v| {
            let (sum, n) = v.iter().filter(|x| x.is_finite()).fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
            (n > 0).then(|| (sum / n as f64).sqrt())
        })
        .collect();
    if sizes.is_empty() {
        return None;
    }
    let middle = sizes.len() / 2;
    Some(*sizes.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// `presses` less their exact [`copies`], and which were left out (`None` when none was).
pub fn without_copies(presses: Vec<LabelledPress>) -> (Vec<LabelledPress>, Option<CopiesLeftOut>) {
    let found = copies(&presses);
    if found.is_empty() {
        return (presses, None);
    }
    let mut kept = vec![true; presses.len()];
    found.iter().for_each(|(copy, _)| kept[*copy] = false);
    let of = presses.len();
    let presses = presses.into_iter().zip(kept).filter(|(_, kept)| *kept).map(|(p, _)| p).collect();
    (presses, Some(CopiesLeftOut { copies: found, of }))
}

/// Trains `method` on `presses` (at least 2, all with forces or none, all with depths or none);
/// press features need `sensor`.
pub fn train(
    presses: &[LabelledPress],
    method: Method,
    sensor: Option<&NominalSensor>,
) -> Result<LearnedModel, LearnError> {
    let (forces, depths) = check(presses, 2)?;
    if method.regressor.reads_press() && method.features != Features::Press {
        return Err(LearnError::NotPressFeatures { method: method.name() });
    }
    let press = match method.features {
        Features::Press => Some(PressFeatures::fit(sensor.ok_or(LearnError::NoSensor)?, presses)?),
        _ => None,
    };
    // Press features learn from the presses that look like one; the others are named.
    let left_out = press.as_ref().map_or(Vec::new(), |p| p.unlike(presses));
    let presses: Vec<&LabelledPress> =
        presses.iter().enumerate().filter(|(i, _)| !left_out.contains(i)).map(|(_, p)| p).collect();
    if presses.len() < 2 {
        return Err(LearnError::FewLikePresses { like: presses.len(), given: presses.len() + left_out.len() });
    }
    let mut scratch = FeatureScratch::default();
    // Every press kept has a fitted press (`unlike` tried the same), one per press, in order.
    let fits: Vec<PressFit> = match &press {
        Some(press) => presses
            .iter()
            .map(|p| press.press_into(&p.inputs, &mut scratch))
            .collect::<Option<_>>()
            .ok_or(LearnError::NotFitted)?,
        None => Vec::new(),
    };
    let inputs: Vec<Vec<f64>> = presses
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut f = Vec::new();
            match fits.get(i) {
                Some(fit) => PressFeatures::of_press_into(fit, &mut f),
                None => method.features.of_into(&p.inputs, &mut f),
            }
            f
        })
        .collect();
    let standardiser = Standardiser::fit(&inputs);
    if standardiser.used().is_empty() {
        return Err(LearnError::NoChannels);
    }
    let points: Vec<Vec<f64>> = inputs
        .iter()
        .map(|row| {
            let mut z = vec![0.0; standardiser.used().len()];
            standardiser.apply_into(row, &mut z);
            z
        })
        .collect();
    let mut targets: Vec<Vec<f64>> = presses
        .iter()
        .map(|p| {
            let mut t = p.position.to_vec();
            t.extend(p.force);
            t.extend(p.depth);
            t
        })
        .collect();
    // A linear term is the physics of press features (the fitted position is nearly the
    // label up to a linear map); on channels it over-fits (at N = 100: 9.7 → 10.7 mm).
    let linear: &[f64] = if press.is_some() { &LINEAR_WEIGHTS } else { &[0.0] };
    let regressor = match method.regressor {
        RegressorKind::Knn { k } if k > points.len() => {
            return Err(LearnError::TooFewForNeighbours { k, presses: points.len() });
        }
        RegressorKind::Knn { k } => Regressor::Knn(Knn::new(k, &points, &targets)),
        RegressorKind::GaussianProcess => {
            Regressor::GaussianProcess(GaussianProcess::fit(&points, &targets, linear).ok_or(LearnError::NotFitted)?)
        }
        RegressorKind::Curve | RegressorKind::CurveResidual => {
            let curves = PressCurves::fit(&fits, &presses)?;
            let residual = if method.regressor == RegressorKind::CurveResidual {
                // What the physics gets wrong, press by press.
                let (mut answer, mut std) = ([0.0; 4], [0.0; 4]);
                for (t, fit) in targets.iter_mut().zip(&fits) {
                    curves.answer_into(fit, &mut answer, &mut std);
                    t.iter_mut().zip(answer).for_each(|(t, a)| *t -= a);
                }
                Some(GaussianProcess::fit(&points, &targets, linear).ok_or(LearnError::NotFitted)?)
            } else {
                None
            };
            Regressor::Curve { curves, residual }
        }
    };
    let input_size = typical_size(presses.iter().map(|p| p.inputs.as_slice())).unwrap_or(f64::NAN);
    Ok(LearnedModel { method, standardiser, regressor, forces, depths, press, left_out, input_size })
}

impl LearnedModel {
    /// The channels that carry nothing (constant, dead, not finite over the training presses),
    /// left out (0-based).
    pub fn dead_channels(&self) -> Vec<usize> {
        match (&self.press, self.method.features) {
            (Some(press), _) => press.dead().to_vec(),
            (None, Features::Shape) => self.standardiser.dead().into_iter().filter(|&c| c < self.channels()).collect(),
            (None, _) => self.standardiser.dead(),
        }
    }

    /// Refuses presses whose inputs are typically ([`typical_size`]) more than
    /// [`SCALE_LIMIT`](crate::inverse::SCALE_LIMIT) times the training presses', or under
    /// 1/[`SCALE_LIMIT`](crate::inverse::SCALE_LIMIT)² of them (light presses may change a frame
    /// ten times less than the training's; a hundred times is another unit): raw frames given to
    /// a model of Δv, another unit or another gain, whose answers would be wrong without a sign.
    pub fn check_scale(&self, presses: &[LabelledPress]) -> Result<(), LearnError> {
        let limit = crate::inverse::SCALE_LIMIT;
        let given = typical_size(presses.iter().map(|p| p.inputs.as_slice()));
        match given.map(|g| g / self.input_size) {
            Some(ratio) if !(ratio > 1.0 / (limit * limit) && ratio < limit) => {
                Err(LearnError::Scale { ratio, given: given.unwrap_or(f64::NAN), trained: self.input_size })
            }
            _ => Ok(()),
        }
    }

    /// Channels a frame must have.
    pub fn channels(&self) -> usize {
        match self.method.features {
            Features::Raw => self.standardiser.channels(),
            Features::Shape => self.standardiser.channels() - 1,
            Features::Press => self.press.as_ref().map_or(0, PressFeatures::channels),
        }
    }

    /// The answer for `frame` (its channels in protocol order; `channels()` of them); `None` for
    /// a frame of another length, and for press features of a frame that looks like no press.
    /// Allocates nothing once `scratch` has grown.
    pub fn predict(&self, frame: &[f64], scratch: &mut PredictScratch) -> Option<Prediction> {
        if frame.len() != self.channels() {
            return None;
        }
        let used = self.standardiser.used().len();
        let fit = match &self.press {
            Some(press) => {
                let fit = press.press_into(frame, &mut scratch.press)?;
                PressFeatures::of_press_into(&fit, &mut scratch.features);
                Some(fit)
            }
            None => {
                self.method.features.of_into(frame, &mut scratch.features);
                None
            }
        };
        scratch.z.resize(used, 0.0);
        self.standardiser.apply_into(&scratch.features, &mut scratch.z);
        // Each output's answer and standard deviation (NaN where the regressor gives none).
        let (mut out, mut std) = ([f64::NAN; 4], [f64::NAN; 4]);
        let outputs = 2 + usize::from(self.forces) + usize::from(self.depths);
        match &self.regressor {
            Regressor::Knn(knn) => knn.predict_into(&scratch.z, &mut scratch.nearest, &mut out[..outputs]),
            Regressor::GaussianProcess(gp) => {
                gp.predict_into(&scratch.z, &mut scratch.gp, &mut out[..outputs], &mut std[..outputs]);
            }
            Regressor::Curve { curves, residual } => {
                curves.answer_into(&fit?, &mut out, &mut std);
                if let Some(gp) = residual {
                    let (mut correction, mut correction_std) = ([0.0; 4], [0.0; 4]);
                    gp.predict_into(
                        &scratch.z,
                        &mut scratch.gp,
                        &mut correction[..outputs],
                        &mut correction_std[..outputs],
                    );
                    out.iter_mut().zip(correction).for_each(|(o, c)| *o += c);
                    // The physics is a function of the frame: its error is what the process knows.
                    std = correction_std;
                }
            }
        }
        let known = |s: f64| s.is_finite().then_some(s);
        // Outputs: x, y, then the force and the depth when trained with them.
        let depth = 2 + usize::from(self.forces);
        Some(Prediction {
            position: [out[0], out[1]],
            force: self.forces.then_some(out[2]),
            position_std: known(std[0].max(std[1])),
            force_std: self.forces.then(|| known(std[2])).flatten(),
            depth: self.depths.then_some(out[depth]),
            depth_std: self.depths.then(|| known(std[depth])).flatten(),
        })
    }
}

/// How well a model answers labelled presses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    /// Mean distance between answer and truth, in m.
    pub mean_position: f64,
    /// Root-mean-square force error, in N (when the presses have forces).
    pub force_rms: Option<f64>,
    /// Root-mean-square depth error, in m (when the presses have depths).
    pub depth_rms: Option<f64>,
    /// Presses the errors are over (those answered).
    pub presses: usize,
    /// Presses the model gave no answer for (press features of a Δv like no press).
    pub unanswered: usize,
}

/// The errors of `model` on `presses`.
pub fn evaluate(model: &LearnedModel, presses: &[LabelledPress]) -> Errors {
    let mut tally = Tally::default();
    tally.add(model, presses);
    tally.errors()
}

/// The errors of `method` by `folds`-fold cross-validation on `presses` (press i in fold
/// i mod folds), pooled over the folds; press features need `sensor`.
pub fn cross_validate(
    presses: &[LabelledPress],
    method: Method,
    folds: usize,
    sensor: Option<&NominalSensor>,
) -> Result<Errors, LearnError> {
    let folds = folds.max(2);
    check(presses, 2 * folds)?;
    let mut tally = Tally::default();
    for fold in 0..folds {
        let (held, kept): (Vec<_>, Vec<_>) = presses.iter().enumerate().partition(|(i, _)| i % folds == fold);
        let kept: Vec<LabelledPress> = kept.into_iter().map(|(_, p)| p.clone()).collect();
        let held: Vec<LabelledPress> = held.into_iter().map(|(_, p)| p.clone()).collect();
        tally.add(&train(&kept, method, sensor)?, &held);
    }
    Ok(tally.errors())
}

/// Sums of answers' errors against their labels.
#[derive(Debug, Default)]
struct Tally {
    distance: f64,
    /// Σ squared error and count, of forces (N²) and depths (m²).
    force: (f64, usize),
    depth: (f64, usize),
    answered: usize,
    unanswered: usize,
}

impl Tally {
    /// Adds `model`'s answers for `presses`.
    fn add(&mut self, model: &LearnedModel, presses: &[LabelledPress]) {
        let mut scratch = PredictScratch::default();
        for p in presses {
            let Some(answer) = model.predict(&p.inputs, &mut scratch) else {
                self.unanswered += 1;
                continue;
            };
            self.record(p, answer.position, answer.force, answer.depth);
        }
    }

    /// Adds an answer given as x, y (m), then the force (N) and the depth (m) where `p` has them;
    /// `None`: unanswered.
    fn answer(&mut self, p: &LabelledPress, answer: Option<&[f64]>) {
        let Some(answer) = answer else {
            self.unanswered += 1;
            return;
        };
        let force = p.force.and(answer.get(2).copied());
        let depth = p.depth.and(answer.get(2 + usize::from(p.force.is_some())).copied());
        self.record(p, [answer[0], answer[1]], force, depth);
    }

    /// Adds one answer against `p`'s labels.
    fn record(&mut self, p: &LabelledPress, position: [f64; 2], force: Option<f64>, depth: Option<f64>) {
        self.answered += 1;
        self.distance += (position[0] - p.position[0]).hypot(position[1] - p.position[1]);
        for (sum, answer, truth) in [(&mut self.force, force, p.force), (&mut self.depth, depth, p.depth)] {
            if let (Some(a), Some(t)) = (answer, truth) {
                sum.0 += (a - t) * (a - t);
                sum.1 += 1;
            }
        }
    }

    fn errors(&self) -> Errors {
        let rms = |(sum, n): (f64, usize)| (n > 0).then(|| (sum / n as f64).sqrt());
        Errors {
            mean_position: self.distance / self.answered.max(1) as f64,
            force_rms: rms(self.force),
            depth_rms: rms(self.depth),
            presses: self.answered,
            unanswered: self.unanswered,
        }
    }
}

/// A candidate's cross-validated errors, or why it could not be cross-validated.
pub type Score = (Method, Result<Errors, LearnError>);

/// The candidate whose cross-validated errors are least, and every candidate's errors (in the
/// order given), or why it could not be cross-validated on these presses (it is then left out
/// of the choice); press features need `sensor`. Least: the smallest sum, over what the presses
/// label (position, force, depth), of the candidate's error over the best candidate's
/// ([`relative_errors`]): on positions alone the smallest mean position error. An error only
/// when no candidate could be: the first one's. `progress` hears of each candidate as it starts.
pub fn choose(
    presses: &[LabelledPress],
    candidates: &[Method],
    folds: usize,
    sensor: Option<&NominalSensor>,
    progress: crate::Progress<'_>,
) -> Result<(Method, Vec<Score>), LearnError> {
    let mut scores: Vec<Score> = Vec::with_capacity(candidates.len());
    for (k, &m) in candidates.iter().enumerate() {
        progress(&format!("cross-validation · {}", m.name()), k, candidates.len());
        scores.push((m, cross_validate(presses, m, folds, sensor)));
    }
    progress("cross-validation", candidates.len(), candidates.len());
    let best = relative_errors(&scores)
        .into_iter()
        .zip(&scores)
        .filter_map(|(relative, (m, _))| Some((*m, relative?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|s| s.0);
    match best {
        Some(best) => Ok((best, scores)),
        None if scores.is_empty() => Err(LearnError::TooFewPresses { got: 0, needed: 2 }),
        None => Err(scores.swap_remove(0).1.err().unwrap_or(LearnError::NotFitted)),
    }
}

/// Each score's errors relative to the best: the sum over the labelled quantities (mean
/// position error, force RMS, depth RMS) of its error over the smallest any candidate has
/// (so 1 per quantity for the best at it); `None` for a candidate that could not be scored or
/// whose errors are not numbers.
/// The presses' answers count as one more quantity, its error the share unanswered plus one
/// (press features give none for a Δv like no press).
pub fn relative_errors(scores: &[Score]) -> Vec<Option<f64>> {
    let quantities = |e: &Errors| {
        let unanswered = e.unanswered as f64 / (e.presses + e.unanswered).max(1) as f64;
        [Some(e.mean_position), e.force_rms, e.depth_rms, Some(1.0 + unanswered)]
    };
    // A score that is not a number (a method overflowed on the presses) is no score.
    let scored = |errors: &Result<Errors, LearnError>| {
        errors.as_ref().ok().filter(|e| quantities(e).into_iter().flatten().all(f64::is_finite)).copied()
    };
    let mut best = [f64::INFINITY; 4];
    for (_, errors) in scores {
        if let Some(e) = scored(errors) {
            for (b, q) in best.iter_mut().zip(quantities(&e)) {
                *b = b.min(q.unwrap_or(f64::INFINITY));
            }
        }
    }
    scores
        .iter()
        .map(|(_, errors)| {
            let e = &scored(errors)?;
            let ratio = |(q, b): (Option<f64>, &f64)| q.map_or(0.0, |q| if *b > 0.0 { q / b } else { 1.0 });
            Some(quantities(e).into_iter().zip(&best).map(ratio).sum())
        })
        .collect()
}

/// The training-set sizes of learning curves: 25, 50, 100, 200, 500 and 1,000 presses.
pub const CURVE_SIZES: [usize; 6] = [25, 50, 100, 200, 500, 1000];

/// One method's learning curve: its errors on the held-out presses when trained on the first N
/// presses, for each N of the curve (`None` where it could not be trained).
#[derive(Debug, Clone, PartialEq)]
pub struct LearningCurve {
    /// The method.
    pub method: Method,
    /// (N, its errors) for each size.
    pub points: Vec<(usize, Option<Errors>)>,
}

/// Every candidate's learning curve on `held_out`, trained on the first N of `training` for the
/// sizes of [`CURVE_SIZES`] that `training` has; with press features when `sensor`. `progress`
/// hears of each method as it starts.
pub fn learning_curves(
    training: &[LabelledPress],
    held_out: &[LabelledPress],
    sensor: Option<&NominalSensor>,
    progress: crate::Progress<'_>,
) -> Vec<LearningCurve> {
    let sizes: Vec<usize> = CURVE_SIZES.into_iter().filter(|&n| n <= training.len()).collect();
    let methods = Method::candidates(sensor.is_some());
    let mut curves = Vec::with_capacity(methods.len());
    for (k, &method) in methods.iter().enumerate() {
        progress(&format!("learning curves · {}", method.name()), k, methods.len());
        let points = sizes
            .iter()
            .map(|&n| (n, train(&training[..n], method, sensor).ok().map(|m| evaluate(&m, held_out))))
            .collect();
        curves.push(LearningCurve { method, points });
    }
    progress("learning curves", methods.len(), methods.len());
    curves
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip_and_bad_ones_are_refused() {
        for method in Method::candidates(true) {
            assert_eq!(Method::from_name(&method.name()), Some(method));
        }
        assert_eq!(Method::from_name("knn-0"), None);
        assert_eq!(Method::from_name("svm"), None);
        // The physics reads the fitted press: on channels it is no method.
        assert_eq!(Method::from_name("curve"), None);
        assert_eq!(Method::from_name("gp-curve-shape"), None);
        assert!(!Method::candidates(false).iter().any(|m| m.regressor.reads_press()));
    }

    /// The choice weighs each labelled quantity by the best candidate's error at it: the one
    /// that is nearly best at both beats one best at position and far off in force.
    #[test]
    fn the_choice_weighs_position_and_force_alike() {
        let errors = |position: f64, force: f64, unanswered: usize| Errors {
            mean_position: position,
            force_rms: Some(force),
            depth_rms: None,
            presses: 100 - unanswered,
            unanswered,
        };
        let scores: Vec<Score> = vec![
            (Method::knn(1), Ok(errors(0.003, 1.0, 0))),
            (Method::knn(3), Ok(errors(0.0033, 0.5, 0))),
            (Method::knn(5), Err(LearnError::NotFitted)),
            (Method::knn(10), Ok(errors(0.0033, 0.5, 20))),
        ];
        let relative = relative_errors(&scores);
        assert_eq!(relative[0], Some(1.0 + 2.0 + 1.0));
        assert!((relative[1].unwrap() - (1.1 + 1.0 + 1.0)).abs() < 1e-12);
        assert_eq!(relative[2], None);
        assert!((relative[3].unwrap() - (1.1 + 1.0 + 1.2)).abs() < 1e-12);
        // A method whose errors are not numbers is no candidate, and moves no one's.
        let mut overflowed = scores;
        overflowed.push((Method::knn(2), Ok(errors(f64::NAN, f64::NAN, 0))));
        let again = relative_errors(&overflowed);
        assert_eq!((&again[..4], again[4]), (&relative[..], None));
    }

    /// A candidate that cannot be cross-validated on the presses (here press features without
    /// the sensor) is left out of the choice with its reason; the others are compared; with no
    /// candidate left, the first one's reason.
    #[test]
    fn a_method_that_cannot_use_the_presses_drops_out_of_the_choice() {
        let presses: Vec<LabelledPress> = (0..20)
            .map(|i| {
                let x = f64::from(i) / 20.0;
                LabelledPress { inputs: vec![x, x * x, 1.0 - x], position: [x, 0.0], force: None, depth: None }
            })
            .collect();
        let press = Method::from_name("gp-press").unwrap();
        let candidates = [press, Method::knn(1), Method::from_name("gp").unwrap()];
        let (best, scores) = choose(&presses, &candidates, 4, None, &mut |_, _, _| {}).unwrap();
        assert_ne!(best, press);
        assert_eq!(scores[0].1, Err(LearnError::NoSensor));
        assert!(scores[1..].iter().all(|(_, e)| e.is_ok()), "{scores:?}");
        assert_eq!(choose(&presses, &[press], 4, None, &mut |_, _, _| {}).unwrap_err(), LearnError::NoSensor);
    }

    #[test]
    fn presses_that_disagree_are_refused() {
        // Each at its own place: the first input's value along x.
        let press = |inputs: Vec<f64>, force| LabelledPress { position: [inputs[0], 0.0], inputs, force, depth: None };
        let mixed = [press(vec![1.0, 2.0], Some(1.0)), press(vec![2.0, 1.0], None)];
        assert_eq!(train(&mixed, Method::knn(1), None).unwrap_err(), LearnError::MixedForces { press: 2 });
        let lengths = [press(vec![1.0, 2.0], None), press(vec![2.0], None)];
        assert_eq!(
            train(&lengths, Method::knn(1), None).unwrap_err().to_string(),
            "press 2 has 1 channels, the first press 2"
        );
        let mut flat = [press(vec![1.0], None), press(vec![1.0], None)];
        flat[1].position[0] = 2.0;
        assert_eq!(train(&flat, Method::knn(1), None).unwrap_err(), LearnError::NoChannels);
        // Presses all at one place tell no place from another.
        let one_place = [press(vec![1.0, 2.0], None), press(vec![1.0, 1.0], None)];
        assert_eq!(
            train(&one_place, Method::knn(1), None).unwrap_err().to_string(),
            "every one of the 2 presses is labelled at (1 m, 0 m): a model of position needs presses at two places or more"
        );
        // A label that is not a number would poison every answer.
        let mut unlabelled = [press(vec![1.0, 2.0], Some(1.0)), press(vec![2.0, 1.0], Some(f64::NAN))];
        assert_eq!(
            train(&unlabelled, Method::knn(1), None).unwrap_err().to_string(),
            "press 2's force is NaN: every label must be a finite number"
        );
        unlabelled[1].force = Some(2.0);
        unlabelled[0].position[1] = f64::INFINITY;
        assert!(matches!(
            train(&unlabelled, Method::knn(1), None),
            Err(LearnError::LabelNotFinite { press: 1, label: "y", .. })
        ));
        // More neighbours than presses would answer their mean everywhere.
        let few = [press(vec![1.0, 2.0], None), press(vec![2.0, 1.0], None), press(vec![3.0, 0.0], None)];
        let refused = train(&few, Method::knn(5), None).unwrap_err();
        assert_eq!(refused.to_string(), "knn-5 needs at least 5 presses to learn from, and has 3: give a smaller k");
        assert!(train(&few, Method::knn(3), None).is_ok());
    }

    /// A press pasted again is named as a copy of the first, and only an exact copy: another
    /// frame at the same place, or the same frame with another force, is a press of its own.
    #[test]
    fn exact_copies_are_named_and_nothing_else() {
        let press = |x: f64, inputs: Vec<f64>, force| LabelledPress { inputs, position: [x, 0.0], force, depth: None };
        let presses = [
            press(0.0, vec![1.0, 2.0], Some(1.0)),
            press(0.0, vec![1.0, 2.5], Some(1.0)),
            press(0.0, vec![1.0, 2.0], Some(2.0)),
            press(0.0, vec![1.0, 2.0], Some(1.0)),
            press(0.1, vec![1.0, 2.0], Some(1.0)),
            press(0.0, vec![1.0, 2.5], Some(1.0)),
        ];
        assert_eq!(copies(&presses), vec![(3, 0), (5, 1)]);
        assert!(copies(&presses[..3]).is_empty());
        let (kept, left_out) = without_copies(presses.to_vec());
        assert_eq!(kept, presses[..3].iter().chain(&presses[4..5]).cloned().collect::<Vec<_>>());
        assert!(left_out
            .unwrap()
            .to_string()
            .starts_with("2 of 6 presses repeat an earlier one exactly (press 4 of 1, 6 of 2)"));
    }
}
