//! `eitskin learn`: a model from labelled presses to where a press is (and how hard, when the
//! presses have forces), every method side by side by cross-validation, and learning curves;
//! `eitskin robot-presses`: labelled presses from the imperfect virtual skin, to learn on.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use eitskin::learn::{
    choose, evaluate, train, Errors, Features, LabelledPress, LearningCurve, Method, NominalSensor, PressFeatures,
};
use eitskin::sim::imperfect::{disc_radius, ImperfectSkin, Imperfections};
use eitskin::{LengthUnit, SensorSpec};

use crate::{load, outputs, plot, ranges};

/// Flags of `eitskin learn`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Samples file (CSV): `x`, `y` (the spec's units), optional `force` (N) and `depth` (the
    /// spec's units), then each press's channels (Δv, or frames) in protocol order.
    #[arg(long)]
    samples: PathBuf,
    /// Write the chosen model here (JSON).
    #[arg(long, value_parser = outputs::writes(&["json"]))]
    out: Option<PathBuf>,
    /// Samples to report the trained model's error on (held out of training).
    #[arg(long)]
    held_out: Option<PathBuf>,
    /// Frames at rest (one, or many: their mean), when the samples hold raw frames: each
    /// press's Δv is its frame less this reference. Text, MAT or NPY, as `calibrate` reads them.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Learning curves: every method trained on the first N = 25, 50, 100, 200, 500, 1000
    /// presses (as many as there are), its error on the held-out samples (needs --held-out).
    #[arg(long)]
    curve: bool,
    /// Also draw the learning curves into this folder (made if missing):
    /// `learning_position.png` and, with forces, `learning_force.png` (needs --curve).
    #[arg(long, requires = "curve")]
    plots: Option<PathBuf>,
    /// Folds of the cross-validation that chooses the method, 2–20.
    #[arg(long, default_value_t = 5, value_parser = ranges::whole("a number of folds", 2, 20))]
    folds: usize,
    /// Train this method instead of choosing: knn-K (K ≥ 1) or gp, either with -shape or -press
    /// (the press fitted on the spec's sensor as specified; Δv of the protocol's length only),
    /// or on the fitted press curve-press (the physics alone) or gp-curve-press (with a learned
    /// residual).
    #[arg(long)]
    method: Option<String>,
}

/// Flags of `eitskin robot-presses`.
#[derive(Debug, clap::Args)]
pub struct PressesArgs {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Presses, 1–1,000,000.
    #[arg(long, default_value_t = 1000, value_parser = ranges::whole("a number of presses", 1, 1_000_000))]
    count: usize,
    /// Write the samples here (CSV, the format `learn` reads).
    #[arg(long, value_parser = outputs::writes(&["csv"]))]
    out: PathBuf,
    /// Also write this many more presses of the same skin, 0–1,000,000, to --held-out.
    #[arg(long, default_value_t = 0, value_parser = ranges::whole("a number of presses", 0, 1_000_000))]
    held_out_count: usize,
    /// Where the held-out presses go (needed with --held-out-count).
    #[arg(long, value_parser = outputs::writes(&["csv"]))]
    held_out: Option<PathBuf>,
    /// Frames averaged for each state (before, pressed), 1–10,000: the robot holds still while
    /// the board streams.
    #[arg(long, default_value_t = 32, value_parser = ranges::whole("a number of frames", 1, 10_000))]
    frames_per_press: usize,
    /// Relative noise per value and frame, 0–0.1 (open boards: 0.003–0.005).
    #[arg(long, default_value_t = 0.003, value_parser = ranges::number("a relative noise", "[0, 0.1]", "0.003", |v| (0.0..=0.1).contains(&v)))]
    noise: f64,
    /// Radius of the disc the presses fall in, as a fraction of the outline's half-width, (0, 1].
    #[arg(long, default_value_t = 0.8, value_parser = ranges::number("a fraction", "(0, 1]", "0.8", |v| v > 0.0 && v <= 1.0))]
    radius: f64,
    /// The skin as specified instead of as built (no outline, electrode, gain, dead-drive,
    /// drift or magnitude error; noise and averaging still apply).
    #[arg(long)]
    perfect: bool,
    /// The skin built as a circle of the outline's area (10 % larger), not the spec's outline.
    #[arg(long, conflicts_with = "perfect")]
    circle: bool,
    /// Seed of the skin's errors, the presses and the noise, 0–2⁶⁴−1.
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    seed: u64,
}

/// The labelled presses of a samples file (positions in m), each less `reference` when the file
/// holds raw frames.
fn presses(path: &Path, spec: &SensorSpec, reference: Option<&(PathBuf, Vec<f64>)>) -> Result<Vec<LabelledPress>> {
    let mut presses = eitskin_io::read_labelled_presses(path, spec)?;
    // A press is one frame of the protocol or several (complex pairs, the frames a board sends
    // per press): a whole number of the protocol's measurements.
    let channels = spec.protocol()?.len();
    if let Some(first) = presses.first().filter(|p| p.inputs.len() % channels != 0) {
        bail!(
            "{}: presses have {} channels; the sensor's protocol has {channels} measurements",
            path.display(),
            first.inputs.len()
        );
    }
    if let Some((file, frame)) = reference {
        let ratio = eitskin::inverse::typical_ratio_of_frames(presses.iter().map(|p| p.inputs.as_slice()), frame);
        if let Some(ratio) = ratio.filter(|r| !eitskin::inverse::plausible_ratio(*r)) {
            bail!(
                "{}: the presses' values are typically {ratio:.3} times those of --reference {} (the median over presses and channels): a press changes them by percents; give --reference with raw frames of the same unit and gain (Δv needs none)",
                path.display(),
                file.display()
            );
        }
        for (k, p) in presses.iter_mut().enumerate() {
            if p.inputs.len() != frame.len() {
                bail!(
                    "{}: press {} has {} values, the reference {} has {}",
                    path.display(),
                    k + 1,
                    p.inputs.len(),
                    file.display(),
                    frame.len()
                );
            }
            p.inputs.iter_mut().zip(frame).for_each(|(v, r)| *v -= r);
        }
    }
    Ok(presses)
}

/// The reference frame at `path`, if given, with its path: the mean of the frames it holds (one,
/// or many at rest, read as `calibrate --reference` reads them).
fn reference(path: Option<&Path>) -> Result<Option<(PathBuf, Vec<f64>)>> {
    let Some(path) = path else { return Ok(None) };
    let table = eitskin_io::read_frames(path, &eitskin_io::FrameSelect::default())?;
    if table.imaginary.is_some() {
        bail!(
            "--reference {}: holds complex values; give the frames at rest as the samples hold them, (re, im) pairs or magnitudes, as real numbers",
            path.display()
        );
    }
    if table.frames.is_empty() {
        bail!("--reference {}: holds no frame", path.display());
    }
    for (k, frame) in table.frames.iter().enumerate() {
        if let Some(c) = frame.iter().position(|v| !v.is_finite()) {
            bail!("--reference {}: frame {} channel {} is not a number", path.display(), k + 1, c + 1);
        }
    }
    Ok(Some((path.to_path_buf(), eitskin::inverse::mean_frame(&table.frames))))
}

/// Runs `eitskin learn`: the presses read, every method scored by cross-validation beside a
/// plain kernel ridge, the best (or the one asked for) trained, then scored on held-out presses.
pub fn run(args: Args) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    if let Some(out) = &args.out {
        let mut inputs = vec![("samples", args.samples.as_path())];
        inputs.extend(args.held_out.as_deref().map(|p| ("--held-out", p)));
        inputs.extend(args.reference.as_deref().map(|p| ("--reference", p)));
        outputs::check(&[("--out", out.as_path())], &inputs)?;
    }
    let forced = args
        .method
        .as_deref()
        .map(|m| {
            Method::from_name(m).with_context(|| {
                format!("{m:?} is not a method: give knn-K (K ≥ 1) or gp, either with -shape or -press, or curve-press or gp-curve-press")
            })
        })
        .transpose()?;
    if args.curve && args.held_out.is_none() {
        bail!("--curve needs --held-out: the curves are errors on presses kept out of training");
    }
    if let Some(dir) = &args.plots {
        outputs::check_folder("--plots", dir)?;
    }
    let (training, held_out) = read_presses(&args, &spec)?;
    let sensor = nominal_sensor(&spec, &training, forced)?;
    let started = Instant::now();
    let mut bars = crate::progress::Bars::default();
    let mut shown = |stage: &str, done: usize, all: usize| bars.update(stage, done, all);
    let candidates = Method::candidates(sensor.is_some());
    let (method, scores) = choose(&training, &candidates, args.folds, sensor.as_ref(), &mut shown)?;
    bars.finish();
    print_scores(&args, &training, &scores, started.elapsed().as_secs_f64());
    let baseline = eitskin::learn::baseline(&training, args.folds);
    print_baseline(&baseline);
    if let Some(sensor) = &sensor {
        print_unlike(sensor, &training)?;
    }
    let method = forced.unwrap_or(method);
    let started = Instant::now();
    let model = train(&training, method, sensor.as_ref())?;
    println!("trained {} on {} presses in {:.2} s", method.name(), training.len(), started.elapsed().as_secs_f64());
    let dead = model.dead_channels();
    if !dead.is_empty() {
        let list: Vec<String> = dead.iter().map(|c| (c + 1).to_string()).collect();
        println!("channels that carry nothing (left out): {}", list.join(", "));
    }
    if let Some(held) = &held_out {
        print_held_out(&model, held, &baseline);
    }
    if args.curve {
        if let Some(held) = &held_out {
            let curves = learning_curves(&training, held, sensor.as_ref());
            if let Some(dir) = &args.plots {
                std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
                let largest = held.iter().filter_map(|p| p.force).fold(0.0, f64::max);
                for path in write_learning_figures(&curves, (largest > 0.0).then_some(largest), dir)? {
                    println!("wrote {}", path.display());
                }
            }
        }
    }
    if let Some(out) = &args.out {
        let text = eitskin_io::learned_model_to_json(&spec, method, &training)?;
        let mut staged = outputs::Staged::default();
        std::fs::write(staged.path(out), text).with_context(|| format!("cannot write {}", out.display()))?;
        staged.commit()?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

/// The training presses and the held-out ones, each against the reference when one is given;
/// held-out presses of another channel count are refused.
fn read_presses(args: &Args, spec: &SensorSpec) -> Result<(Vec<LabelledPress>, Option<Vec<LabelledPress>>)> {
    let reference = reference(args.reference.as_deref())?;
    let training = without_copies(presses(&args.samples, spec, reference.as_ref())?, &args.samples);
    let held_out = args.held_out.as_deref().map(|p| presses(p, spec, reference.as_ref())).transpose()?;
    if let (Some(held), Some(path), Some(first)) = (&held_out, args.held_out.as_deref(), training.first()) {
        if let Some((k, p)) = held.iter().enumerate().find(|(_, p)| p.inputs.len() != first.inputs.len()) {
            bail!(
                "{}: press {} has {} channels, and the training presses of {} have {}",
                path.display(),
                k + 1,
                p.inputs.len(),
                args.samples.display(),
                first.inputs.len()
            );
        }
        // A press learned from is no test of what was learned.
        let seen =
            held.iter().filter(|h| training.iter().any(|t| t.position == h.position && t.inputs == h.inputs)).count();
        if seen == held.len() {
            bail!(
                "{}: every held-out press is also one of the training presses of {}: hold out presses the model does not learn from",
                path.display(),
                args.samples.display()
            );
        }
        if seen > 0 {
            eprintln!(
                "warning: {}: {seen} of {} held-out presses are also training presses; their errors flatter the model",
                path.display(),
                held.len()
            );
        }
    }
    Ok((training, held_out))
}

/// `presses` less their exact copies, which a warning names.
fn without_copies(presses: Vec<LabelledPress>, path: &Path) -> Vec<LabelledPress> {
    let (kept, left_out) = eitskin::learn::without_copies(presses);
    if let Some(left_out) = left_out {
        eprintln!("warning: {}: {left_out}", path.display());
    }
    kept
}

/// The sensor as specified, for press features, when the presses are Δv of the protocol's
/// values; a press method asked for without it is refused.
fn nominal_sensor(
    spec: &SensorSpec,
    training: &[LabelledPress],
    forced: Option<Method>,
) -> Result<Option<eitskin::learn::NominalSensor>> {
    let channels = spec.protocol()?.len();
    // Press features read Δv on the sensor as specified: one value per measurement.
    let sensor = match training.first() {
        Some(p) if p.inputs.len() == channels => Some(load::nominal_sensor("learn", spec)?),
        _ => None,
    };
    if let (Some(m), None) = (forced, &sensor) {
        if m.features == Features::Press {
            bail!("--method {}: press features need Δv of the protocol's {channels} values a press", m.name());
        }
    }
    Ok(sensor)
}

/// The cross-validation's table: each method's mean position error and force (and depth) RMS,
/// or why it was left out.
fn print_scores(
    args: &Args,
    training: &[LabelledPress],
    scores: &[(Method, Result<Errors, eitskin::learn::LearnError>)],
    seconds: f64,
) {
    let mm = |m: f64| m * 1e3;
    println!("{}-fold cross-validation on {} presses ({seconds:.2} s):", args.folds, training.len());
    let depths = training.first().is_some_and(|p| p.depth.is_some());
    let depth_header = if depths { format!(" {:>14}", "depth RMS (mm)") } else { String::new() };
    println!("  {:14} {:>14} {:>14}{depth_header}", "method", "position (mm)", "force RMS (N)");
    for (m, e) in scores {
        let e = match e {
            Ok(e) => e,
            // A method that cannot use these presses drops out of the choice; the others go on.
            Err(why) => {
                println!("  {:14} left out: {why}", m.name());
                continue;
            }
        };
        let force = e.force_rms.map_or("—".into(), |f| format!("{f:.2}"));
        let depth = e.depth_rms.map_or(String::new(), |d| format!(" {:>14.3}", mm(d)));
        let unanswered = if e.unanswered > 0 { format!("  ({} unanswered)", e.unanswered) } else { String::new() };
        println!("  {:14} {:>14.1} {:>14}{depth}{unanswered}", m.name(), mm(e.mean_position), force);
    }
}

/// The plain baseline, scored on the same folds: what the choice has to beat.
fn print_baseline(baseline: &Result<eitskin::learn::Baseline, eitskin::learn::LearnError>) {
    let mm = |m: f64| m * 1e3;
    match baseline {
        Ok(b) => println!(
            "  plain kernel ridge (RBF on the z-scored channels, ℓ {} and λ {} by the same folds): {:.1} mm{}",
            b.model.length_scale,
            b.model.lambda,
            mm(b.errors.mean_position),
            b.errors.force_rms.map_or(String::new(), |f| format!(", force RMS {f:.2} N"))
        ),
        Err(why) => println!("  plain kernel ridge: not fitted: {why}"),
    }
}

/// The presses whose Δv look like no press on the sensor as specified.
fn print_unlike(sensor: &eitskin::learn::NominalSensor, training: &[LabelledPress]) -> Result<()> {
    let unlike = PressFeatures::fit(sensor, training)?.unlike(training);
    if !unlike.is_empty() {
        let list: Vec<String> = unlike.iter().map(|i| (i + 1).to_string()).collect();
        println!(
            "{} of {} presses' Δv look like no press on the sensor as specified, left out of the -press methods: {}",
            unlike.len(),
            training.len(),
            list.join(", ")
        );
    }
    Ok(())
}

/// The model's errors on the held-out presses, and the plain kernel ridge's.
fn print_held_out(
    model: &eitskin::learn::LearnedModel,
    held: &[LabelledPress],
    baseline: &Result<eitskin::learn::Baseline, eitskin::learn::LearnError>,
) {
    let mm = |m: f64| m * 1e3;
    let e = evaluate(model, held);
    let force = e.force_rms.map_or(String::new(), |f| format!(", force RMS {f:.2} N"));
    let depth = e.depth_rms.map_or(String::new(), |d| format!(", depth RMS {:.3} mm", mm(d)));
    println!(
        "on {} held-out presses: mean position error {:.1} mm{force}{depth}{}",
        e.presses,
        mm(e.mean_position),
        unanswered(&e)
    );
    if let Ok(b) = baseline {
        let e = eitskin::learn::evaluate_baseline(&b.model, held);
        let force = e.force_rms.map_or(String::new(), |f| format!(", force RMS {f:.2} N"));
        println!("  the plain kernel ridge on them: {:.1} mm{force}", mm(e.mean_position));
    }
}

/// Every method trained on the first N presses, its errors on `held`, as tables: mean position
/// error, and force and depth RMS when the presses have them.
fn learning_curves(
    training: &[LabelledPress],
    held: &[LabelledPress],
    sensor: Option<&NominalSensor>,
) -> Vec<LearningCurve> {
    let mut bars = crate::progress::Bars::default();
    let curves = eitskin::learn::learning_curves(training, held, sensor, &mut |s, d, a| bars.update(s, d, a));
    bars.finish();
    let header: String = curves
        .first()
        .map_or(String::new(), |c| c.points.iter().map(|(n, _)| format!("{:>9}", format!("N={n}"))).collect());
    let labelled = |label: fn(&LabelledPress) -> bool| !held.is_empty() && held.iter().all(label);
    let tables: [(&str, usize, bool, &crate::report::Reading<'_>); 3] = [
        ("mean position error (mm)", 1, true, &|e| Some(e.mean_position * 1e3)),
        ("force RMS (N)", 2, labelled(|p| p.force.is_some()), &|e| e.force_rms),
        ("depth RMS (mm)", 3, labelled(|p| p.depth.is_some()), &|e| e.depth_rms.map(|d| d * 1e3)),
    ];
    for (title, digits, _, reading) in tables.iter().filter(|t| t.2) {
        println!("learning curves: {title} on {} held-out presses", held.len());
        println!("  {:14}{header}", "method");
        for curve in &curves {
            let row: String = curve
                .points
                .iter()
                .map(|(_, e)| match e.as_ref().and_then(reading) {
                    Some(v) => format!("{v:>9.digits$}"),
                    None => format!("{:>9}", "—"),
                })
                .collect();
            println!("  {:14}{row}", curve.method.name());
        }
    }
    curves
}

/// The learning curves as figures in `dir`, N on a log axis, one line per method: the mean
/// position error (`learning_position.png`) and, when `max_force` (N) is given, the force RMS as
/// a percentage of it (`learning_force.png`); the paths written.
pub fn write_learning_figures(curves: &[LearningCurve], max_force: Option<f64>, dir: &Path) -> Result<Vec<PathBuf>> {
    let series = |value: &dyn Fn(&Errors) -> Option<f64>| -> Vec<plot::Series> {
        curves
            .iter()
            .map(|c| plot::Series {
                name: c.method.name(),
                points: c.points.iter().filter_map(|(n, e)| Some((*n as f64, value(e.as_ref()?)?))).collect(),
                line: true,
            })
            .collect()
    };
    let position = dir.join("learning_position.png");
    plot::chart_log_x(
        &position,
        "Learned calibration: position error against training presses",
        ("training presses N", "mean position error on held-out presses (mm)"),
        &series(&|e| Some(e.mean_position * 1e3)),
    )?;
    let mut written = vec![position];
    if let Some(max_force) = max_force {
        let force = dir.join("learning_force.png");
        plot::chart_log_x(
            &force,
            "Learned calibration: force error against training presses",
            ("training presses N", "force RMS on held-out presses (% of the largest force)"),
            &series(&|e| e.force_rms.map(|f| 100.0 * f / max_force)),
        )?;
        written.push(force);
    }
    Ok(written)
}

/// "; N presses answered nothing (…)" when a model gave no answer for some presses.
fn unanswered(e: &Errors) -> String {
    match e.unanswered {
        0 => String::new(),
        n => format!("; {n} more presses got no answer (their Δv looks like no press on the spec's sensor)"),
    }
}

/// Runs `eitskin robot-presses`.
pub fn presses_run(args: PressesArgs) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    let mut written = vec![("--out", args.out.as_path())];
    match (&args.held_out, args.held_out_count) {
        (Some(path), n) if n > 0 => written.push(("--held-out", path.as_path())),
        (None, 0) => {}
        _ => bail!("--held-out and --held-out-count go together (a file and a count above 0)"),
    }
    outputs::check(&written, &[])?;
    let imperfections = if args.perfect {
        Imperfections {
            scale: 1.0,
            electrode_shift: 0.0,
            gain_spread: 0.0,
            dead_drive: None,
            drift_per_press: 0.0,
            magnitudes: false,
            ..Imperfections::default()
        }
    } else {
        Imperfections::default()
    };
    let imperfections = Imperfections {
        noise_relative: args.noise,
        frames_per_press: args.frames_per_press,
        circle: args.circle,
        ..imperfections
    };
    let radius = disc_radius(&spec.outline, args.radius);
    let started = Instant::now();
    let mut skin = ImperfectSkin::new(&spec, &imperfections, args.seed)?;
    let mut bars = crate::progress::Bars::default();
    let mut staged = outputs::Staged::default();
    let mut written = Vec::new();
    for (path, count) in [(Some(&args.out), args.count), (args.held_out.as_ref(), args.held_out_count)] {
        let Some(path) = path.filter(|_| count > 0) else { continue };
        let mut pressed = Vec::with_capacity(count);
        let stage = format!("robot presses for {}", path.display());
        for k in 0..count {
            // One at a time: the same presses as all at once (each draws from the skin in turn).
            bars.update(&stage, k, count);
            pressed.extend(skin.robot_presses(1, radius, 2.0..16.0)?);
        }
        bars.update(&stage, count, count);
        let comment =
            "eitskin robot-presses: x, y in the spec's units, force in N, then Δv (pressed less before) per channel";
        let csv = eitskin_io::labelled_presses_to_csv(&pressed, spec.length_unit.metres(), comment);
        std::fs::write(staged.path(path), csv).with_context(|| format!("cannot write {}", path.display()))?;
        written.push(format!(
            "wrote {} presses to {} ({:.1} s)",
            pressed.len(),
            path.display(),
            started.elapsed().as_secs_f64()
        ));
    }
    bars.finish();
    staged.commit()?;
    written.iter().for_each(|line| eprintln!("{line}"));
    Ok(())
}

/// `eitskin evaluate --model`: the model's errors on the presses of `samples` (less the frame at
/// `reference`, when they are raw frames).
pub fn evaluate_model(
    spec: &SensorSpec,
    model: &Path,
    samples: &Path,
    reference_frame: Option<&Path>,
    out: Option<&Path>,
) -> Result<()> {
    // The model's presses and these agree in their channels as `learn` read them.
    let held = presses(samples, spec, reference(reference_frame)?.as_ref())?;
    let channels = held.first().map_or(spec.protocol()?.len(), |p| p.inputs.len());
    let learned = eitskin_io::read_learned_model(model, spec, channels, eitskin_io::build::cache_dir().as_deref())?;
    learned
        .check_scale(&held)
        .with_context(|| format!("{} against the model {}", samples.display(), model.display()))?;
    let e = evaluate(&learned, &held);
    println!(
        "{} on {} presses of {}: mean position error {:.1} mm{}",
        learned.method.name(),
        e.presses,
        samples.display(),
        e.mean_position * 1e3,
        unanswered(&e)
    );
    if let Some(rms) = e.depth_rms {
        println!("depth RMS {:.3} mm", rms * 1e3);
    }
    if let Some(rms) = e.force_rms {
        let largest = held.iter().filter_map(|p| p.force).fold(0.0, f64::max);
        if largest > 0.0 {
            println!("force RMS {rms:.2} N ({:.1} % of the largest force, {largest:.1} N)", 100.0 * rms / largest);
        } else {
            println!("force RMS {rms:.2} N (no percentage: every labelled force is 0 N)");
        }
    }
    if let Some(out) = out {
        let mut staged = outputs::Staged::default();
        std::fs::write(staged.path(out), answers_csv(&learned, &held, spec.length_unit))
            .with_context(|| format!("writing {}", out.display()))?;
        staged.commit()?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

/// Each press's label and `model`'s answer as CSV, lengths in `unit`, forces in N; a blank
/// where the press has no such label or the model no such answer (a Δv like no press).
fn answers_csv(model: &eitskin::learn::LearnedModel, presses: &[LabelledPress], unit: LengthUnit) -> String {
    let (per_unit, u) = (1.0 / unit.metres(), unit.symbol());
    let mut csv = format!(
        "sample,x_{u},y_{u},force_n,depth_{u},answered,predicted_x_{u},predicted_y_{u},position_std_{u},predicted_force_n,force_std_n,predicted_depth_{u},depth_std_{u}\n"
    );
    let cell =
        |v: Option<f64>, scale: f64| v.filter(|v| v.is_finite()).map_or(String::new(), |v| format!("{}", v * scale));
    let mut scratch = eitskin::learn::PredictScratch::default();
    for (k, p) in presses.iter().enumerate() {
        let answer = model.predict(&p.inputs, &mut scratch);
        let cells = [
            cell(Some(p.position[0]), per_unit),
            cell(Some(p.position[1]), per_unit),
            cell(p.force, 1.0),
            cell(p.depth, per_unit),
            u8::from(answer.is_some()).to_string(),
            cell(answer.map(|a| a.position[0]), per_unit),
            cell(answer.map(|a| a.position[1]), per_unit),
            cell(answer.and_then(|a| a.position_std), per_unit),
            cell(answer.and_then(|a| a.force), 1.0),
            cell(answer.and_then(|a| a.force_std), 1.0),
            cell(answer.and_then(|a| a.depth), per_unit),
            cell(answer.and_then(|a| a.depth_std), per_unit),
        ];
        csv += &format!("{},{}\n", k + 1, cells.join(","));
    }
    csv
}
