//! `eitskin study`: the paper's simulation and in-silico experiment rerun on the virtual sensor,
//! every force method side by side; figures (PNG), numbers (JSON), `report.md`, and the frames
//! it measured (CSV) for `eitskin calibrate` and `evaluate`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use eitskin::study::sweep::{self, SweepParams, SweepReport};
use eitskin::study::{run as run_study, StudyParams, StudyReport};
use eitskin::LengthUnit;

use crate::{load, plot, ranges, report};

/// Flags of `eitskin study`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Folder for the figures, `study.json` and `report.md`.
    #[arg(long, default_value = "study")]
    out: PathBuf,
    /// Seed of the noise and the validation presses, 0 to 2⁶⁴ − 1.
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    seed: u64,
    /// Measurement noise, relative standard deviation per value, in [0, 0.1] (default 1e-4 =
    /// 80 dB).
    #[arg(long, value_parser = ranges::number("a relative noise", "[0, 0.1]", "1e-4", |n| (0.0..=0.1).contains(&n)))]
    noise: Option<f64>,
    /// Validation presses, 1–100,000 (475 in the paper).
    #[arg(long, value_parser = ranges::whole("a number of validation presses", 1, 100_000))]
    validation: Option<usize>,
    /// Noisy frames per calibration press, 1–1,000 (15 in the paper).
    #[arg(long, value_parser = ranges::whole("a number of frames per press", 1, 1000))]
    repeats: Option<usize>,
    /// Noise sweep: frames with one press per press kind and level, and as many with two and
    /// with three (300: a share found near 95 % is known to about ±2.5 points, at 60 it was ±5;
    /// a pair's force RMS, which a few strong presses dominate, to about ±20 %, and at half as
    /// many frames one seed's RMS lay 30 % from another's), 0–10,000; 0 leaves the sweep out.
    #[arg(long, default_value_t = 300, value_parser = ranges::whole("a number of presses", 0, 10_000))]
    sweep_presses: usize,
    /// Noise sweep: untouched frames per level, for the false touches, 1–100,000 (10,000: a
    /// rate of 1 per 1,000 is then about 10 ± 3 false touches, not 1 ± 1).
    #[arg(long, default_value_t = 10_000, value_parser = ranges::whole("a number of frames", 1, 100_000))]
    sweep_untouched: usize,
    /// Learned calibration: robot presses of the imperfect virtual skin to train on, 0–10,000
    /// (the learning curves go up to it; 0 leaves the section out); 300 more are held out.
    #[arg(long, default_value_t = 500, value_parser = ranges::whole("a number of presses", 0, 10_000))]
    learning_presses: usize,
}

/// Runs `eitskin study`.
pub fn run(args: Args) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    // The folder is made first, so that a path that cannot be one fails before the work.
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut params = StudyParams { seed: args.seed, ..StudyParams::default() };
    if let Some(n) = args.noise {
        params.sim.noise_relative = n;
    }
    if let Some(n) = args.validation {
        params.validation = n;
    }
    if let Some(n) = args.repeats {
        params.repeats = n;
    }
    let start = Instant::now();
    let mut last = String::new();
    let mut progress = |stage: &str, done: usize, all: usize| {
        if stage != last || done == all {
            eprintln!("[{:>5.1} s] {stage} {done}/{all}", start.elapsed().as_secs_f64());
            last = stage.to_string();
        }
    };
    let study = run_study(&spec, &params, &mut progress)?;
    let sweep = match args.sweep_presses {
        0 => None,
        n => {
            let sweep_params = SweepParams {
                scenes: [n; 3],
                untouched: args.sweep_untouched,
                seed: args.seed,
                ..SweepParams::default()
            };
            Some(sweep::run(&spec, &sweep_params, &mut progress)?)
        }
    };
    let learning = match args.learning_presses {
        0 => None,
        n => {
            progress("learned calibration: robot presses and learning curves", 0, 1);
            Some(eitskin::study::learning::run(&spec, n, args.seed)?)
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    write_figures(&study, &args, spec.length_unit)?;
    let mut json = report::json(&study, &params, seconds);
    if let (Some(sweep), Some(object)) = (&sweep, json.as_object_mut()) {
        object.insert("sweep".into(), report::sweep_json(sweep));
        write_sweep_figures(sweep, &args, spec.length_unit)?;
    }
    if let (Some(learning), Some(object)) = (&learning, json.as_object_mut()) {
        object.insert("learning".into(), report::learning_json(learning));
        crate::learn::write_learning_figures(&learning.curves, Some(learning.max_force), &args.out)?;
    }
    std::fs::write(args.out.join("study.json"), serde_json::to_string_pretty(&json)?)?;
    write_frames(&study, &args, spec.length_unit.metres())?;
    let mut markdown = report::markdown(&study, &params, spec.length_unit, seconds);
    if let Some(sweep) = &sweep {
        markdown += &report::sweep_markdown(sweep, spec.length_unit);
    }
    if let Some(learning) = &learning {
        markdown += &report::learning_markdown(learning);
    }
    std::fs::write(args.out.join("report.md"), &markdown)?;
    println!("{markdown}");
    eprintln!("wrote {} in {seconds:.1} s", args.out.display());
    Ok(())
}

/// The frames the study measured, for `eitskin calibrate` and `evaluate` to reproduce its
/// numbers: `reference.csv` (one frame), `calibration_frames.csv` and `validation_frames.csv`
/// (`x,y,force,v1…`: the press's centre in the spec's units, its force, its noisy frame).
fn write_frames(study: &StudyReport, args: &Args, metres: f64) -> Result<()> {
    let values = |csv: &mut String, frame: &[f64]| frame.iter().for_each(|v| csv.push_str(&format!(",{v:e}")));
    let reference: Vec<String> = study.reference.iter().map(|v| format!("{v:e}")).collect();
    std::fs::write(args.out.join("reference.csv"), reference.join("\n") + "\n")?;
    for (name, frames) in
        [("calibration_frames.csv", &study.calibration), ("validation_frames.csv", &study.validation_frames)]
    {
        let mut csv = String::from("x,y,force");
        (1..=study.reference.len()).for_each(|m| csv.push_str(&format!(",v{m}")));
        for f in frames {
            csv.push_str(&format!("\n{},{},{}", f.position[0] / metres, f.position[1] / metres, f.force));
            values(&mut csv, &f.frame);
        }
        csv.push('\n');
        std::fs::write(args.out.join(name), csv)?;
    }
    Ok(())
}

/// The study's figures, lengths in `unit` (the spec's).
fn write_figures(study: &StudyReport, args: &Args, unit: LengthUnit) -> Result<()> {
    let xs: Vec<f64> = study.profile.iter().map(|p| p.0[0] / unit.metres()).collect();
    let ys: Vec<f64> = study.profile.iter().map(|p| p.1).collect();
    plot::chart(
        &args.out.join("fig3c_location.png"),
        "Fig. 3c: reconstructed peak along x",
        (&format!("x ({})", unit.symbol()), "peak |Δσ| (S/m)"),
        &[plot::Series { name: "peak".into(), points: xs.into_iter().zip(ys).collect(), line: true }],
    )?;
    let curves: Vec<plot::Series> = study
        .simulated_curves
        .iter()
        .enumerate()
        .map(|(k, (drops, peaks))| plot::Series {
            name: format!("area {}", k + 1),
            points: drops.iter().copied().zip(peaks.iter().copied()).collect(),
            line: true,
        })
        .collect();
    plot::chart(
        &args.out.join("fig4b_areas.png"),
        "Fig. 4b: peak against conductivity drop, per area",
        ("drop (fraction of the background)", "peak |Δσ| (S/m)"),
        &curves,
    )?;
    for (k, method) in study.methods.iter().enumerate() {
        let points: Vec<(f64, f64)> = study
            .validation
            .iter()
            .zip(&method.predicted)
            .filter(|(_, p)| p.is_finite())
            .map(|(t, p)| (t.force, *p))
            .collect();
        let diagonal = plot::Series { name: "ideal".into(), points: vec![(0.0, 0.0), (16.0, 16.0)], line: true };
        let dots = plot::Series { name: method.method.name(), points, line: false };
        plot::chart(
            &args.out.join(format!("fig12_{}.png", k + 1)),
            &format!("Fig. 12: true against predicted force, {}", method.method.name()),
            ("true force (N)", "predicted force (N)"),
            &[diagonal, dots],
        )?;
    }
    Ok(())
}

/// The sweep's figures: position error and force RMS of single presses found in Δv against the
/// noise, one line per press kind (single frames only).
fn write_sweep_figures(sweep: &SweepReport, args: &Args, unit: LengthUnit) -> Result<()> {
    let kinds: Vec<&str> = sweep::press_kinds().iter().map(|k| k.name).collect();
    let line = |kind: &str, value: &dyn Fn(&sweep::SweepRow) -> f64| plot::Series {
        name: kind.to_string(),
        points: sweep
            .rows
            .iter()
            .filter(|r| r.kind == kind && r.presses == 1 && r.method == "presses in Δv" && r.level.average == 1)
            .map(|r| (r.level.db, value(r)))
            .collect(),
        line: true,
    };
    let position: Vec<plot::Series> = kinds.iter().map(|k| line(k, &|r| r.position_error / unit.metres())).collect();
    plot::chart(
        &args.out.join("sweep_position.png"),
        "One press found in Δv: position error against noise",
        ("noise (dB below each value)", &format!("mean position error ({})", unit.symbol())),
        &position,
    )?;
    let mut force: Vec<plot::Series> =
        kinds.iter().map(|k| line(k, &|r| 100.0 * r.force_rms / sweep.max_force)).collect();
    // Beside each kind, as dots, what no unbiased estimate from Δv can beat.
    force.extend(kinds.iter().map(|k| plot::Series {
        name: format!("{k}: Cramér–Rao bound"),
        line: false,
        ..line(k, &|r| 100.0 * r.force_rms_bound / sweep.max_force)
    }));
    plot::chart(
        &args.out.join("sweep_force.png"),
        "One press: force RMS against noise (one curve of the fitted drop)",
        ("noise (dB below each value)", "force RMS (% of the largest force)"),
        &force,
    )
}
