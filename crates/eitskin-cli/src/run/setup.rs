//! What `eitskin run` builds before its first frame: the calibration (a file's, or the virtual
//! sensor's made now), the learned model, the imaging, the chain and the pipeline's settings.

use std::path::PathBuf;

use anyhow::{bail, Result};
use eitskin::calibration::Strength;
use eitskin::inverse::Hyperparameter;
use eitskin::pipeline::{NoiseFloor, Pipeline, PipelineParams};
use eitskin::press_fit::TableUse;
use eitskin::pseudo_array::PseudoArray;
use eitskin::{ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::build::ChainSetup;
use eitskin_io::source::SourceSpec;

use super::imaging::{self, Imaging};
use super::learned::LearnedAnswers;
use super::Args;
use crate::load;

/// The precision a sensor's frames are imaged in (`--precision`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Precision {
    /// Half where the matrices read every frame overflow the last-level cache, and through the
    /// basis sensors of one spec in one process share once λ is chosen from their noise; else
    /// single.
    Auto,
    /// The reconstruction matrix itself, in f32.
    Single,
    /// A binary16 copy of it: half the bytes a frame reads.
    Half,
}

/// What one press's tabulated response is used for in fitting presses (`--press-table`): the
/// press model's `TableUse` of the same name, or none. (Each line is the flag's help.)
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PressTable {
    /// Fitted on the table while it holds, exactly from there (the default)
    Auto,
    /// Fitted on the table throughout (presses nearer than five radii with one exact solve a fit)
    Fit,
    /// Each exact fit of presses five radii apart started from a fit on the table
    Start,
    /// No table: exact fits from the linear search's places
    Off,
}

/// Sets the pipelines whose precision is `auto` to half precision where the matrices every
/// pipeline reads each frame overflow the last-level cache (bytes as the pipelines now read
/// them), those of them that share their linearisation with another pipeline (sensors of one
/// spec in one process) to image through their shared basis once their λ is chosen from their
/// noise, and says so once, as `command`.
pub fn choose_precision(command: &str, pipelines: &mut [(Precision, &mut Pipeline)]) {
    let bytes: usize = pipelines.iter().map(|(_, p)| p.chain().reconstructor().matrix().bytes_read()).sum();
    let Some(cache) = eitskin_io::last_level_cache() else { return };
    let auto = pipelines.iter().filter(|(precision, _)| *precision == Precision::Auto).count();
    // Matrices that overflow the cache are read from memory every frame: half the bytes take
    // about half the time; a basis that several sensors share is read once for all of them.
    if bytes as f64 <= cache || auto == 0 {
        return;
    }
    let linearisation = |p: &Pipeline| std::sync::Arc::clone(p.chain().reconstructor().linearisation());
    let all: Vec<_> = pipelines.iter().map(|(_, p)| linearisation(p)).collect();
    let shares = |k: usize| all.iter().enumerate().any(|(j, lin)| j != k && std::sync::Arc::ptr_eq(lin, &all[k]));
    let mut sharing = 0;
    for (k, (_, pipeline)) in
        pipelines.iter_mut().enumerate().filter(|(_, (precision, _))| *precision == Precision::Auto)
    {
        if shares(k) {
            pipeline.set_shared_basis(true);
            sharing += 1;
        }
        pipeline.set_half_precision(true);
    }
    let matrices =
        if pipelines.len() == 1 { "the matrix's".to_owned() } else { format!("{} matrices'", pipelines.len()) };
    let shared = match sharing {
        0 => String::new(),
        n => format!(", {n} of them through the basis their spec shares once λ is chosen from their noise"),
    };
    eprintln!(
        "eitskin {command}: imaging in half precision ({auto} of {}{shared}): {matrices} {:.1} MiB overflow the {:.1} MiB last-level cache (--precision single keeps single)",
        pipelines.len(),
        bytes as f64 / MIB,
        cache / MIB
    );
}

/// Bytes in a mebibyte, as processors' caches are said.
const MIB: f64 = 1024.0 * 1024.0;

/// What a run processes frames with.
pub struct Built {
    /// The pipeline, its reference not yet taken.
    pub pipeline: Pipeline,
    /// The pipeline's settings.
    pub params: PipelineParams,
    /// λ and normalisation, as asked or as the calibration fixes them.
    pub imaging: Imaging,
    /// The learned model's answers, with `--model`.
    pub learned: Option<LearnedAnswers>,
}

/// Builds what `args` ask for `spec`'s sheet.
pub fn build(args: &Args, spec: &SensorSpec) -> Result<Built> {
    let calibration = match &args.calibration {
        Some(path) => Some((path.clone(), eitskin_io::read_calibration_file(path, spec)?)),
        None if args.virtual_calibration => Some(virtual_calibration(spec, args)?),
        None => None,
    };
    // A learned model of this sensor's frames, trained again from its presses: another
    // protocol's or channel count's is refused before any work.
    let learned = match &args.model {
        Some(path) => {
            let cache = eitskin_io::build::cache_dir();
            let model = eitskin_io::read_learned_model(path, spec, spec.protocol()?.len(), cache.as_deref())?;
            eprintln!("eitskin run: learned model {} ({})", path.display(), model.method.name());
            Some(LearnedAnswers::new(model))
        }
        None => None,
    };
    let imaging = imaging::resolve(
        args.hyperparameter.as_ref(),
        args.normalised,
        calibration.as_ref().map(|(path, file)| (path.as_path(), file.imaging)),
    )?;
    let params = PipelineParams {
        reference_frames: args.reference_frames,
        reference_limit: args.reference_limit,
        baseline_rate: args.baseline_rate,
        auto_hyperparameter: imaging.hyperparameter == Hyperparameter::Auto,
        noise_floor: NoiseFloor::FalseAlarm { rate: args.false_alarm_rate },
        average: args.average,
        carry_presses: !args.fresh_presses,
    };
    let pipeline = load::pipeline("run", spec, chain_setup(args, imaging, calibration), params)?;
    if args.average > 1 {
        let frames = pipeline.latency_frames();
        let at = if args.rate > 0.0 {
            format!(" ({:.0} ms at {} frames/s)", 1e3 * frames / args.rate, args.rate)
        } else {
            String::new()
        };
        eprintln!(
            "eitskin run: averaging {} frames delays a change by {frames} frames on average{at}; the reference takes {} frames",
            args.average,
            params.frames_in_reference()
        );
    }
    Ok(Built { pipeline, params, imaging, learned })
}

/// The chain `args` ask for, imaging as `imaging` says, with the calibration's curves when
/// there is one.
fn chain_setup(
    args: &Args,
    imaging: Imaging,
    calibration: Option<(PathBuf, eitskin_io::CalibrationFile)>,
) -> ChainSetup {
    let recon = ReconstructorParams {
        hyperparameter: match imaging.hyperparameter {
            Hyperparameter::Fixed(value) => value,
            // Chosen once the reference frames are in; until then, the paper's.
            Hyperparameter::Auto => ReconstructorParams::default().hyperparameter,
        },
        normalised: imaging.normalised,
        ..ReconstructorParams::default()
    };
    let touch = TouchParams { polarity: args.polarity, peak_of: args.peak_of, ..TouchParams::default() };
    let calibration = calibration.map(|(path, file)| {
        eprintln!(
            "eitskin run: λ = {}, {} differences, as the calibration {} was fitted",
            file.imaging.hyperparameter,
            if file.imaging.normalised { "normalised" } else { "absolute" },
            path.display()
        );
        (file.array, file.calibration)
    });
    let half_precision = args.precision == Precision::Half;
    ChainSetup {
        touch,
        fit: args.fit,
        press_table: press_table(args),
        calibration,
        half_precision,
        ..ChainSetup::new(recon)
    }
}

/// What the press model's table is for (`--press-table`).
fn press_table(args: &Args) -> Option<TableUse> {
    match args.press_table {
        PressTable::Auto => Some(TableUse::Auto),
        PressTable::Fit => Some(TableUse::Fit),
        PressTable::Start => Some(TableUse::Start),
        PressTable::Off => None,
    }
}

/// The virtual sensor's calibration, made now as `calibrate` makes one from a board's presses
/// (frames drawn with another seed than the run's), and what to call it in messages.
fn virtual_calibration(spec: &SensorSpec, args: &Args) -> Result<(PathBuf, eitskin_io::CalibrationFile)> {
    if !matches!(args.source, SourceSpec::Sim { .. }) {
        bail!("--virtual-calibration calibrates the virtual sensor: it goes with --source sim");
    }
    eprintln!(
        "eitskin run: calibrating the virtual sensor as the paper does (six unit centres, 0–15 N, one frame each)…"
    );
    let started = std::time::Instant::now();
    let strength = Strength::FittedDrop;
    let setup =
        ChainSetup { strength, press_table: press_table(args), ..ChainSetup::new(ReconstructorParams::default()) };
    let chain = load::chain("run", spec, setup)?;
    let array = PseudoArray::of_sensor(spec, [5, 5])?;
    let sim = eitskin::sim::SimParams::default();
    let seed = args.seed ^ 0x00ca_11b0;
    let (calibration, found) = eitskin_study::users::calibrate_virtual(spec, sim, seed, chain, &array, 20)?;
    eprintln!(
        "eitskin run: {:.0} % of the calibration presses found, {} curves of the fitted drop ({:.1} s)",
        100.0 * found,
        calibration.curves.len(),
        started.elapsed().as_secs_f64()
    );
    let imaging = eitskin_io::Imaging::default();
    Ok((PathBuf::from("of the virtual sensor"), eitskin_io::CalibrationFile { array, calibration, imaging }))
}
