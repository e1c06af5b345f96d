//! The one builder of what a sensor's frames go through, for every front end (the CLI and
//! Python alike): the linearisation and reconstructor without the channels the spec drops, λ,
//! the press model, the contrast map and the frame chain, each from the on-disk cache when
//! there is one ([`cache_dir`]), the live [`pipeline`] with its settings checked, and the
//! reconstructor of an image taken against frames at rest ([`ReferenceImaging`]).

use std::path::PathBuf;
use std::sync::Arc;

use eitskin::calibration::Calibration;
use eitskin::chain::Chain;
use eitskin::contrast_map::{ContrastMap, ContrastMapParams};
use eitskin::inverse::{
    choose_hyperparameter, Channels, HyperparameterRule, Linearisation, Reference, Weighting, WeightingUsed,
};
use eitskin::pipeline::{Pipeline, PipelineParams};
use eitskin::press_fit::{PressModel, PressModelParams, TableUse};
use eitskin::pseudo_array::PseudoArray;
use eitskin::strength::Strength;
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

use crate::Error;

/// Where precomputed models are cached: `$EITSKIN_CACHE`, else `$XDG_CACHE_HOME/eitskin`, else
/// `~/.cache/eitskin`; `None` when none of these is set.
pub fn cache_dir() -> Option<PathBuf> {
    let var = |name| std::env::var_os(name).filter(|v| !v.is_empty()).map(PathBuf::from);
    var("EITSKIN_CACHE")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("eitskin")))
        .or_else(|| var("HOME").map(|d| d.join(".cache/eitskin")))
}

/// The cache to use: [`cache_dir`] when `use_cache`, else none.
fn cache(use_cache: bool) -> Option<PathBuf> {
    cache_dir().filter(|_| use_cache)
}

/// The linearisation of `spec`, from the cache when there is one (and `use_cache`).
pub fn linearisation(spec: &SensorSpec, use_cache: bool) -> Result<Arc<Linearisation>, Error> {
    Ok(match cache(use_cache) {
        Some(dir) => crate::shared_linearisation(&dir, spec)?.0,
        None => Arc::new(Linearisation::new(&spec.forward_model()?, spec.conductivity)?),
    })
}

/// The reconstructor of `spec` with `params`, from the cache when there is one (and
/// `use_cache`), without the channels the spec's mask drops.
pub fn reconstructor(spec: &SensorSpec, params: &ReconstructorParams, use_cache: bool) -> Result<Reconstructor, Error> {
    let recon = match cache(use_cache) {
        Some(dir) => crate::load_or_build(&dir, spec, params)?.0,
        None => Reconstructor::new(&spec.forward_model()?, spec.conductivity, params)?,
    };
    let used = spec.used_channels()?;
    if used.contains(&false) {
        return Ok(recon.derive(params.hyperparameter, Channels::all(used.len()).masked(&used))?);
    }
    Ok(recon)
}

/// The automatic λ of `lin` (of `spec`) for `params` and the noise-weighted `channels`
/// ([`choose_hyperparameter`]), from the cache when chosen before for exactly these (and
/// `use_cache`).
pub fn auto_hyperparameter(
    spec: &SensorSpec,
    lin: &Linearisation,
    params: &ReconstructorParams,
    channels: &Channels,
    use_cache: bool,
) -> Result<f64, Error> {
    let choose = || choose_hyperparameter(lin, &params.prior, params.normalised, channels);
    Ok(match cache(use_cache) {
        Some(dir) => crate::cached_hyperparameter(&dir, spec, params, channels, || Ok(choose()?))?.0,
        None => choose()?,
    })
}

/// The press model of `spec` (default indenter), from the cache when there is one.
pub fn press_model(spec: &SensorSpec) -> Result<PressModel, Error> {
    let params = PressModelParams::default();
    match cache_dir() {
        Some(dir) => Ok(crate::load_or_build_press_model(&dir, spec, &params)?.0),
        None => crate::build_press_model(spec, &params),
    }
}

/// Whether the press model of `spec` (default indenter) is in the cache; where it is not,
/// [`press_model`] builds it (seconds on the paper's sheet, longer on finer meshes).
pub fn press_model_cached(spec: &SensorSpec) -> bool {
    let path = cache_dir().and_then(|dir| crate::press_model_path(&dir, spec, &PressModelParams::default()).ok());
    path.is_some_and(|path| path.is_file())
}

/// What a frame chain is built from, besides its spec: the settings every front end gives.
#[derive(Debug, Clone)]
pub struct ChainSetup {
    /// The reconstructor's parameters (λ, normalisation, prior).
    pub recon: ReconstructorParams,
    /// How touches are found.
    pub touch: TouchParams,
    /// How a touch's strength is read; with a calibration, the calibration's own.
    pub strength: Strength,
    /// Fit a press to each touch (on by itself when the strength needs the press model).
    pub fit: bool,
    /// What one press's exact response tabulated is for, if it is made (not cached: tabulated
    /// at each setup, about 0.36 s on two cores and 41 MiB on the paper's sheet): fits on it
    /// while it holds ([`TableUse::Auto`], [`TableUse::DEFAULT`]), throughout
    /// ([`TableUse::Fit`]), or exact fits started from it ([`TableUse::Start`]), as `run
    /// --press-table auto|fit|start`; `None`: no table (`--press-table off`).
    pub press_table: Option<TableUse>,
    /// The pseudo-array and curves that turn strengths into forces, N.
    pub calibration: Option<(PseudoArray, Calibration)>,
    /// Image frames from a half-precision copy of the matrix ([`Chain::set_half_precision`]).
    pub half_precision: bool,
}

impl ChainSetup {
    /// The chain of `recon` reading each touch's peak, with the default touch settings, no fit
    /// and no calibration.
    pub fn new(recon: ReconstructorParams) -> ChainSetup {
        ChainSetup {
            recon,
            touch: TouchParams::default(),
            strength: Strength::Peak,
            fit: false,
            press_table: TableUse::DEFAULT,
            calibration: None,
            half_precision: false,
        }
    }

    /// Whether building it needs the press model (seconds on the paper's sheet, unless cached).
    pub fn needs_press_model(&self) -> bool {
        self.fit || self.strength().needs_press_model()
    }

    /// The strength read: the calibration's, else the one asked for.
    pub fn strength(&self) -> Strength {
        self.calibration.as_ref().map_or(self.strength, |(_, c)| c.strength)
    }
}

/// The frame chain of `spec` as `setup` says: the reconstructor (from the cache, without the
/// channels the spec drops), the press model when the strength needs it or `fit` asks for it,
/// the contrast map when the strength reads it, and the calibration.
pub fn chain(spec: &SensorSpec, setup: ChainSetup) -> Result<Chain, Error> {
    let strength = setup.strength();
    let recon = reconstructor(spec, &setup.recon, true)?;
    let map = if strength.needs_contrast_map() {
        let map_params = ContrastMapParams::default();
        Some(match cache_dir() {
            Some(dir) => crate::load_or_build_contrast_map(&dir, spec, &recon, &map_params)?.0,
            None => {
                ContrastMap::new(&spec.forward_model()?, spec.conductivity, &recon, spec.outline.bounds(), &map_params)?
            }
        })
    } else {
        None
    };
    let mut chain = Chain::new(recon, setup.touch);
    if setup.needs_press_model() {
        let press_model = press_model(spec)?;
        chain = chain.with_press_model(press_model.with_table_use(setup.press_table)?);
    }
    if let Some(map) = map {
        chain = chain.with_contrast_map(map);
    }
    chain = chain.with_strength(strength)?;
    if let Some((array, calibration)) = setup.calibration {
        chain = chain.with_calibration(array, calibration)?;
    }
    chain.set_half_precision(setup.half_precision);
    Ok(chain)
}

/// The live pipeline of `spec`: `params` checked against their ranges before anything is
/// built, then the chain of `setup`.
pub fn pipeline(spec: &SensorSpec, setup: ChainSetup, params: PipelineParams) -> Result<Pipeline, Error> {
    params.check()?;
    Ok(Pipeline::new(chain(spec, setup)?, params))
}

/// The reconstructor of images taken against frames at rest, as `image` makes it: λ by its rule,
/// the channels weighted as asked, and what was chosen.
#[derive(Debug)]
pub struct ReferenceImaging {
    /// The reconstructor, derived for the data's channels and λ.
    pub recon: Reconstructor,
    /// The reference (mean and measured noise) the frames are imaged against.
    pub reference: Reference,
    /// How the channels were weighted.
    pub weighting: WeightingUsed,
    /// What chose λ ([`HyperparameterRule::chosen_by`]).
    pub chosen_by: &'static str,
}

impl ReferenceImaging {
    /// The reconstructor of `spec`'s linearisation `lin` (from [`linearisation`]) with `params`
    /// (λ there is ignored: `rule` sets it) for images of `frames` against `references` (both
    /// signed, as long as the protocol, missing channels NaN: see
    /// [`eitskin::inverse::mark_missing`]); the channels weighted by `weighting`, or by the
    /// rule's default; the automatic λ from the cache when there is one (and `use_cache`).
    pub fn new(
        spec: &SensorSpec,
        lin: &Arc<Linearisation>,
        params: &ReconstructorParams,
        (references, frames): (&[Vec<f64>], &[Vec<f64>]),
        (rule, weighting): (HyperparameterRule, Option<Weighting>),
        use_cache: bool,
    ) -> Result<ReferenceImaging, Error> {
        let reference = Reference::new(references);
        let weighting = weighting.unwrap_or(rule.default_weighting());
        let (channels, weighting) = reference.channels(lin, params.normalised, frames, weighting);
        let auto = || auto_hyperparameter(spec, lin, params, &channels, use_cache);
        let hyperparameter =
            reference.hyperparameter(rule, lin, (&params.prior, params.normalised), &channels, frames, auto)?;
        let params = ReconstructorParams { hyperparameter, ..*params };
        let recon = Reconstructor::from_linearisation(Arc::clone(lin), &params, channels)?;
        Ok(ReferenceImaging { recon, reference, weighting, chosen_by: rule.chosen_by() })
    }
}

/// `spec` as specified, for a learned model's press features (its press model from the cache
/// when there is one).
pub fn nominal_sensor(spec: &SensorSpec) -> Result<eitskin::learn::NominalSensor, Error> {
    crate::nominal_sensor(spec, cache_dir().as_deref())
}
