//! `eitskin study`: the paper's simulation and in-silico experiment rerun on the virtual sensor,
//! every force method side by side; figures (PNG), numbers (JSON), `report.md`, and the frames
//! it measured (CSV) for `eitskin calibrate` and `evaluate`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use eitskin::LengthUnit;
use eitskin_study::sweep::{self, SweepParams, SweepReport};
use eitskin_study::users::{self, UsersParams, UsersReport};
use eitskin_study::{run as run_study, StudyParams, StudyReport};

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
    /// many frames one seed's RMS lay 30 % from another's), 0–10,000; 0 (the default) leaves the
    /// sweep out: `--sweep-presses 300` runs it (about 6 minutes on 2 cores).
    #[arg(long, default_value_t = 0, value_parser = ranges::whole("a number of presses", 0, 10_000))]
    sweep_presses: usize,
    /// Noise sweep: untouched frames per level, for the false touches, 1–100,000 (10,000: a
    /// rate of 1 per 1,000 is then about 10 ± 3 false touches, not 1 ± 1).
    #[arg(long, default_value_t = 10_000, value_parser = ranges::whole("a number of frames", 1, 100_000))]
    sweep_untouched: usize,
    /// Learned calibration: robot presses of the imperfect virtual skin to train on, 0–10,000
    /// (the learning curves go up to it; 0, the default, leaves the section out: 500 gives the
    /// curves to 500 presses); 300 more are held out.
    #[arg(long, default_value_t = 0, value_parser = ranges::whole("a number of presses", 0, 10_000))]
    learning_presses: usize,
    /// Calibrate as users do (the paper's six units, or random robot presses) and validate at
    /// random places elsewhere on presses of kinds the press model does not assume, at 0.01 %,
    /// 0.05 % and 0.2 % noise, through `calibrate`'s and `evaluate`'s path; writes the frames
    /// under `users/` (a few minutes).
    #[arg(long)]
    as_users: bool,
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
    let mut progress = crate::progress::Bars::default();
    let mut report = |stage: &str, done: usize, all: usize| progress.update(stage, done, all);
    let unit = spec.length_unit;
    // Each part's figures, frames and its section of study.json and report.md are written as it
    // ends, so that a run stopped later keeps what was done.
    let study = run_study(&spec, &params, &mut report)?;
    write_figures(&study, &args, unit)?;
    write_frames(&study, &args, unit.metres())?;
    let mut json = report::json(&study, &params, start.elapsed().as_secs_f64());
    let mut markdown = report::markdown(&study, &params, unit, start.elapsed().as_secs_f64());
    write_report(&args, &json, &markdown)?;
    let mut add = |key: &str, value: serde_json::Value, section: String| {
        if let Some(object) = json.as_object_mut() {
            object.insert(key.into(), value);
        }
        markdown += &section;
        write_report(&args, &json, &markdown)
    };
    if args.sweep_presses > 0 {
        let n = args.sweep_presses;
        let sweep_params =
            SweepParams { scenes: [n; 3], untouched: args.sweep_untouched, seed: args.seed, ..SweepParams::default() };
        let sweep = sweep::run(&spec, &sweep_params, &mut report)?;
        write_sweep_figures(&sweep, &args, unit)?;
        add("sweep", report::sweep_json(&sweep), report::sweep_markdown(&sweep, unit))?;
    }
    if args.learning_presses > 0 {
        let learning = eitskin_study::learning::run(&spec, args.learning_presses, args.seed, &mut report)?;
        crate::learn::write_learning_figures(&learning.curves, Some(learning.max_force), &args.out)?;
        add("learning", report::learning_json(&learning), report::learning_markdown(&learning))?;
    }
    if args.as_users {
        let users_params = UsersParams { seed: args.seed, ..UsersParams::default() };
        let users = users::run(&spec, &users_params, &mut report)?;
        write_users_frames(&users, &args, unit.metres())?;
        add("as_users", report::users_json(&users), report::users_markdown(&users, &users_params))?;
    }
    progress.finish();
    println!("{markdown}");
    eprintln!("wrote {} in {:.1} s", args.out.display(), start.elapsed().as_secs_f64());
    Ok(())
}

/// Writes `study.json` and `report.md` with the parts done so far.
fn write_report(args: &Args, json: &serde_json::Value, markdown: &str) -> Result<()> {
    std::fs::write(args.out.join("study.json"), serde_json::to_string_pretty(json)?)?;
    std::fs::write(args.out.join("report.md"), markdown)?;
    Ok(())
}

/// The frames the study measured, for `eitskin calibrate` and `evaluate` to reproduce its
/// numbers: `reference.csv` (the frames at rest, one per line), `calibration_frames.csv` and `validation_frames.csv`
/// (`x,y,force,v1…`: the press's centre in the spec's units, its force, its noisy frame).
fn write_frames(study: &StudyReport, args: &Args, metres: f64) -> Result<()> {
    let values = |csv: &mut String, frame: &[f64]| frame.iter().for_each(|v| csv.push_str(&format!(",{v:e}")));
    let row = |frame: &[f64]| frame.iter().map(|v| format!("{v:e}")).collect::<Vec<_>>().join(",");
    let reference: Vec<String> = study.reference_frames.iter().map(|f| row(f)).collect();
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
    for (k, method) in study.methods.iter().enumerate().filter(|(_, m)| m.refused.is_none()) {
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

/// The frames of the section calibrated as users do, per kind and level, in a folder
/// `users/<kind>_<noise>/`: `rest.csv` (frames at rest, one per line), `paper.csv` and
/// `robot.csv` (calibration samples `x,y,force,v1…`, 0 N rows included), `validation.csv`
/// (single presses), and `pairs.csv` (`x1,y1,force1,x2,y2,force2,v1…`).
fn write_users_frames(users: &UsersReport, args: &Args, metres: f64) -> Result<()> {
    let row = |frame: &[f64]| frame.iter().map(|v| format!("{v:e}")).collect::<Vec<_>>().join(",");
    let channels = |n: usize| (1..=n).map(|m| format!("v{m}")).collect::<Vec<_>>().join(",");
    for frames in &users.frames {
        let name: String =
            frames.kind.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
        let dir = args.out.join("users").join(format!("{name}_{}", frames.noise));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let rest: Vec<String> = frames.rest.iter().map(|f| row(f)).collect();
        std::fs::write(dir.join("rest.csv"), rest.join("\n") + "\n")?;
        let n = frames.rest.first().map_or(0, Vec::len);
        for (file, labelled) in
            [("paper.csv", &frames.paper), ("robot.csv", &frames.robot), ("validation.csv", &frames.validation)]
        {
            let mut csv = format!("x,y,force,{}\n", channels(n));
            for f in labelled {
                csv +=
                    &format!("{},{},{},{}\n", f.position[0] / metres, f.position[1] / metres, f.force, row(&f.frame));
            }
            std::fs::write(dir.join(file), csv)?;
        }
        let mut csv = format!("x1,y1,force1,x2,y2,force2,{}\n", channels(n));
        for (presses, frame) in &frames.pairs {
            for p in presses {
                csv += &format!("{},{},{},", p.position[0] / metres, p.position[1] / metres, p.force);
            }
            csv += &format!("{}\n", row(frame));
        }
        std::fs::write(dir.join("pairs.csv"), csv)?;
    }
    Ok(())
}
