//! The study's numbers as JSON and as a Markdown report beside the paper's.

use eitskin::strength::Strength;
use eitskin::LengthUnit;
use eitskin_study::learning::LearningReport;
use eitskin_study::sweep::SweepReport;
use eitskin_study::users::{UsersParams, UsersReport, COUNTED_FROM, MAX_FORCE, PAIR_APART};
use eitskin_study::{ForceMethod, StudyParams, StudyReport};
use serde_json::{json, Value};

/// The paper's Table 2 (a, b, c, R² per area, its sign convention) and headline figures.
const PAPER_TABLE_2: [(f64, f64, f64, f64); 6] = [
    (-0.0012, -12.9166, 1.1442e-4, 0.89),
    (-0.0017, -11.5566, 7.6769e-4, 0.96),
    (-0.0023, -5.6269, 0.0014, 0.98),
    (-0.0015, -9.8576, 1.1136e-4, 0.96),
    (-0.0023, -5.2634, 7.0521e-4, 0.99),
    (-0.0178, -9.7668, 0.0165, 0.99),
];

/// Everything measured, as one JSON value.
pub fn json(study: &StudyReport, params: &StudyParams, seconds: f64) -> Value {
    let curve = |c: &eitskin::calibration::Curve| json!({"a": c.a, "b_newton": c.b, "c": c.c, "shape": c.shape, "r_squared": c.r_squared, "force_range_newton": c.force_range, "samples": c.samples});
    json!({
        "seconds": seconds,
        "seed": params.seed,
        "noise_relative": params.sim.noise_relative,
        "location_dependence": study.profile.iter().map(|(p, v)| json!({"x_m": p[0], "peak": v})).collect::<Vec<_>>(),
        "simulated_area_fits": study.simulated_fits.iter().map(curve).collect::<Vec<_>>(),
        "validation_presses": study.validation.len(),
        "touches_found": study.validation_touches.iter().filter(|t| t.is_some()).count(),
        "mean_position_error_m": study.mean_position_error,
        "mean_fit_position_error_m": study.mean_fit_position_error,
        "share_in_right_unit": study.right_unit,
        "methods": study.methods.iter().map(|m| json!({
            "name": m.method.name(),
            "grid": m.method.grid,
            "strength": m.method.strength.name(),
            "calibration_samples": m.calibration_samples,
            "curves": m.curves.iter().map(curve).collect::<Vec<_>>(),
            "rms_newton": m.errors.rms,
            "rms_percent_of_max": m.errors.rms_percent_of_max,
            "correlation": m.errors.correlation,
            "mean_absolute_newton": m.errors.mean_absolute,
            "count": m.errors.count,
            "refused": m.refused,
        })).collect::<Vec<_>>(),
    })
}

/// The Markdown report: each result beside the paper's.
pub fn markdown(study: &StudyReport, params: &StudyParams, unit: LengthUnit, seconds: f64) -> String {
    let mut s = String::new();
    s += "# The paper's study, rerun on the virtual sensor\n\n";
    s += &format!(
        "Seed {}, noise {:.1e} of each value ({:.0} dB), {} calibration frames per press, {} validation presses; {seconds:.1} s.\n\n",
        params.seed,
        params.sim.noise_relative,
        -20.0 * params.sim.noise_relative.log10(),
        params.repeats,
        params.validation
    );
    let centre = study.profile[study.profile.len() / 2].1;
    let edge = study.profile.first().map_or(0.0, |p| p.1).max(study.profile.last().map_or(0.0, |p| p.1));
    s += "## Location dependence (Fig. 3c)\n\n![](fig3c_location.png)\n\n";
    s += &format!("Edge-to-centre peak ratio: **{:.2}** (EIDORS on the paper's geometry: 3.3; the paper's Fig. 3c shows the same rise toward the edges).\n\n", edge / centre);
    s += "## Per-area curves in simulation (Fig. 4b)\n\n![](fig4b_areas.png)\n\n| area | a | b | c | R² |\n|---|---|---|---|---|\n";
    for (i, c) in study.simulated_fits.iter().enumerate() {
        s += &format!("| {} | {:.4} | {:.4} | {:.4} | {:.3} |\n", i + 1, c.a, c.b, c.c, c.r_squared);
    }
    let mean_r2 =
        study.simulated_fits.iter().map(|c| c.r_squared).sum::<f64>() / study.simulated_fits.len().max(1) as f64;
    s += &format!("\nMean R² {mean_r2:.3} (paper: 0.99).\n\n");
    s += &calibration_table(study, params);
    s += &validation(study, params, unit);
    s
}

/// Table 2: the per-area curves of the peak (and R² of the fitted press's drop) beside the paper's.
fn calibration_table(study: &StudyReport, params: &StudyParams) -> String {
    let mut s = String::new();
    s += "## Calibration (Table 2)\n\nOurs: peak(F) = a·e^(−F/b) + c with the peak a positive magnitude, so our b > 0 where the paper's (signed conductivity) b < 0; where a curve is a·(1 + F/(k·b))^(−k) + c instead (it fitted better than chance would let it), its b says k.\n\n";
    s += "The column R² (fitted press) is the same per-area fit on the drop of the press fitted to Δv (`eitskin::press_fit`) instead of the image's peak.\n\n";
    s += "| area | a | b [N] | c | R² | R² (fitted press) | forces [N] | samples | paper a | paper b | paper c | paper R² |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let fitted = method(study, params.grid, Strength::FittedDrop);
    if let Some(m) = study.methods.first() {
        for (i, c) in m.curves.iter().enumerate() {
            let r2 = fitted.and_then(|f| f.curves.get(i)).map_or(String::new(), |f| format!("{:.3}", f.r_squared));
            let paper = PAPER_TABLE_2
                .get(i)
                .map_or("| | | | ".to_string(), |p| format!("| {} | {} | {:e} | {} ", p.0, p.1, p.2, p.3));
            let b = c.shape.map_or(format!("{:.3}", c.b), |k| format!("{:.3} (k = {k})", c.b));
            s += &format!(
                "| {} | {:.4e} | {b} | {:.4e} | {:.3} | {r2} | {:.0}–{:.0} | {} {paper}|\n",
                i + 1,
                c.a,
                c.c,
                c.r_squared,
                c.force_range[0],
                c.force_range[1],
                c.samples
            );
        }
    }
    s
}

/// Fig. 12: the validation presses' positions, each force method's errors and figures.
fn validation(study: &StudyReport, params: &StudyParams, unit: LengthUnit) -> String {
    let (k, u) = (1.0 / unit.metres(), unit.symbol());
    let mut s = String::new();
    s += "\n## Force and position on the validation presses (Fig. 12)\n\n";
    let found = study.validation_touches.iter().filter(|t| t.is_some()).count();
    s += &format!(
        "{found} of {} validation presses gave a touch. Mean position error **{:.1} {u}** on a {:.0} {u} sheet (of the fitted press: **{:.1} {u}**); **{:.1} %** of touches in the pressed unit.\n\n",
        study.validation.len(),
        study.mean_position_error * k,
        0.2 * k,
        study.mean_fit_position_error * k,
        100.0 * study.right_unit
    );
    s += "| method | calibration samples | RMS error [N] | RMS [% of max force] | correlation | mean abs. error [N] |\n|---|---|---|---|---|---|\n";
    s += "| paper, experiment (5×5 pseudo-array) | 1245 | 1.62 | 10.15 | 0.91 | |\n";
    for m in &study.methods {
        if let Some(reason) = &m.refused {
            s += &format!("| {} | {} | refused: {reason} | | | |\n", m.method.name(), m.calibration_samples);
            continue;
        }
        s += &format!(
            "| {} | {} | {:.2} | {:.2} | {:.3} | {:.2} |\n",
            m.method.name(),
            m.calibration_samples,
            m.errors.rms,
            m.errors.rms_percent_of_max,
            m.errors.correlation,
            m.errors.mean_absolute
        );
    }
    if let Some(c) = method(study, 1, Strength::FittedDrop).and_then(|m| m.curves.first()) {
        let gel = params.sim.hydrogel;
        s += &format!(
            "\nThe fitted press's one curve, from the calibration presses alone: drop(F) = {:.3} {} {:.3}·e^(−F/{:.2} N); the virtual gel's own law: {:.3}·(1 − e^(−F/{:.2} N)).\n",
            c.c,
            if c.a < 0.0 { "−" } else { "+" },
            c.a.abs(),
            c.b,
            gel.max_drop,
            gel.force_scale
        );
    }
    for (i, m) in study.methods.iter().enumerate().filter(|(_, m)| m.refused.is_none()) {
        s += &format!("\n![{}](fig12_{}.png)\n", m.method.name(), i + 1);
    }
    s
}

/// The study's results of the force method on a `grid` × `grid` pseudo-array reading `strength`.
fn method(study: &StudyReport, grid: usize, strength: Strength) -> Option<&eitskin_study::MethodResult> {
    study.methods.iter().find(|m| m.method == ForceMethod { grid, strength })
}

/// The noise sweep's rows as JSON (distances in m, forces in N).
pub fn sweep_json(sweep: &SweepReport) -> Value {
    let number = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    json!({
        "max_force_newton": sweep.max_force,
        "match_distance_m": eitskin_study::sweep::MATCH_DISTANCE,
        "rows": sweep.rows.iter().map(|r| json!({
            "noise_db": r.level.db,
            "noise_relative": r.level.relative(),
            "frames_averaged": r.level.average,
            "press_kind": r.kind,
            "presses_per_frame": r.presses,
            "method": r.method,
            "frames": r.frames,
            "detection": number(r.detection),
            "detection_95_interval": r.detection_interval.map(number),
            "false_touches_per_1000_frames": r.false_per_1000,
            "mean_position_error_m": number(r.position_error),
            "force_rms_newton": number(r.force_rms),
            "force_rms_percent_of_max": number(100.0 * r.force_rms / sweep.max_force),
            "force_rms_95_interval_percent_of_max": r.force_rms_interval.map(|x| number(100.0 * x / sweep.max_force)),
            "force_within_two_std": number(r.force_within_two_std),
            "force_rms_bound_newton": number(r.force_rms_bound),
            "force_rms_bound_percent_of_max": number(100.0 * r.force_rms_bound / sweep.max_force),
        })).collect::<Vec<_>>(),
    })
}

/// The noise sweep as a Markdown section: the bars at 66 dB (0.05 %) and at 54 dB
/// (0.2 %) with 16 frames averaged, then every row.
pub fn sweep_markdown(sweep: &SweepReport, unit: LengthUnit) -> String {
    let k = 1.0 / unit.metres();
    let u = unit.symbol();
    let found = |r: &eitskin_study::sweep::SweepRow| match r.detection_interval {
        [lo, hi] if r.detection.is_finite() => {
            format!("{:.1} ({:.1}–{:.1})", 100.0 * r.detection, 100.0 * lo, 100.0 * hi)
        }
        _ => "–".into(),
    };
    let len = |x: f64| if x.is_finite() { format!("{:.1}", x * k) } else { "–".into() };
    let force = |x: f64| if x.is_finite() { format!("{:.1}", 100.0 * x / sweep.max_force) } else { "–".into() };
    let force_rms = |r: &eitskin_study::sweep::SweepRow| match r.force_rms_interval {
        [lo, hi] if lo.is_finite() => format!("{} ({}–{})", force(r.force_rms), force(lo), force(hi)),
        _ => force(r.force_rms),
    };
    let mut s = String::from("\n## Noise sweep: presses the methods do not assume, one to three at once\n\n");
    s += "Noise in dB below each value (66 dB = 0.05 %, 54 dB = 0.2 %, 50 dB = 0.32 %: the OpenEIT captures vary 0.3–0.5 %). ";
    s += "Single frames unless averaged; λ and the noise tests from 10 reference frames, as `eitskin run` takes them, the reference then grown to 100 frames on the sheet at rest (× the frames averaged). ";
    s += &format!(
        "A press is found when a touch lies within {:.0} {u}; forces (presses in Δv only) through one curve of the fitted drop, calibrated at each level on single presses of the same kind (the 15 mm indenter through the 10 mm one's: its force is ambiguous for any method); force RMS in % of {:.0} N. Found % with its 95 % interval (Wilson's, of so many presses); force RMS with its 95 % interval (normal in the log of the mean square, frames as the units; approximate where a few presses dominate). The bound beside the force RMS is the Cramér–Rao bound of the press model's drop (centre and drop of every press unknown) through the same curve: what no unbiased estimate from Δv can beat. A force is the mean of its posterior over the calibrated range given its drop and the fit's standard deviation of it (uniform there, as the inverse's clamp assumes), so where the curve flattens it can fall below the bound; each comes with its posterior standard deviation, and the last column says how often the truth lay within twice it (about 95 % if they are honest).\n\n",
        eitskin_study::sweep::MATCH_DISTANCE * k,
        sweep.max_force
    );
    s += "![](sweep_position.png)\n\n![](sweep_force.png)\n\n";
    s += &format!("| dB | averaged | press kind | presses | method | frames | found % | false / 1000 frames | position [{u}] | force RMS [%] | bound [%] | within 2 std [%] |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in &sweep.rows {
        s += &format!(
            "| {:.0} | {} | {} | {} | {} | {} | {} | {:.1} | {} | {} | {} | {} |\n",
            r.level.db,
            r.level.average,
            if r.kind.is_empty() { "untouched" } else { r.kind },
            r.presses,
            r.method,
            r.frames,
            found(r),
            r.false_per_1000,
            len(r.position_error),
            force_rms(r),
            force(r.force_rms_bound),
            if r.force_within_two_std.is_finite() {
                format!("{:.0}", 100.0 * r.force_within_two_std)
            } else {
                "–".into()
            }
        );
    }
    s
}

/// What a table of learning curves reads of a method's errors.
pub(crate) type Reading<'a> = dyn Fn(&eitskin::learn::Errors) -> Option<f64> + 'a;

/// The learned calibration's curves as JSON (distances in m, forces in N).
pub fn learning_json(learning: &LearningReport) -> Value {
    json!({
        "training_presses": learning.training,
        "held_out_presses": learning.held_out,
        "frames_per_press": learning.imperfections.frames_per_press,
        "noise_relative": learning.imperfections.noise_relative,
        "max_force_newton": learning.max_force,
        "curves": learning.curves.iter().map(|c| json!({
            "method": c.method.name(),
            "points": c.points.iter().map(|(n, e)| json!({
                "presses": n,
                "mean_position_error_m": e.map(|e| e.mean_position),
                "force_rms_newton": e.and_then(|e| e.force_rms),
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    })
}

/// The learned calibration as a Markdown section: the mean position error and force RMS of
/// every method against N.
pub fn learning_markdown(learning: &LearningReport) -> String {
    let imperfect = &learning.imperfections;
    let mut s = String::from("\n## Learned calibration: learning curves on an imperfect skin\n\n");
    s += &format!(
        "Robot presses of the virtual skin as built, not as specified (`eitskin robot-presses`): the outline {:.0} % larger, electrodes moved up to {:.0} mm, channel gains ±{:.0} %, the first drive dead, a common drift, magnitudes only, {:.1} % noise per frame and each state the mean of {} frames; presses uniform in a disc over 80 % of the half-width, forces 2–{:.0} N. Each method is trained on the first N presses and tested on {} others (`eitskin learn --curve`); methods named `-press` see the press fitted to Δv on the sensor as specified (where, how strong), the others the channels alone; `curve-press` is the physics alone (the fitted centre, and the force its drop gives on one curve fitted to the N presses) and `gp-curve-press` the physics with a Gaussian process on what it gets wrong. The bars: ≤ 5 mm at N = 100; every learned method ≥ 25 % better than k-nearest neighbours at N = 100 and 500; force RMS ≤ 5 % of the largest force.\n\n",
        100.0 * (imperfect.scale - 1.0),
        imperfect.electrode_shift * 1e3,
        100.0 * imperfect.gain_spread,
        100.0 * imperfect.noise_relative,
        imperfect.frames_per_press,
        learning.max_force,
        learning.held_out
    );
    s += "![](learning_position.png)\n\n![](learning_force.png)\n\n";
    let sizes: Vec<usize> = learning.curves.first().map_or(Vec::new(), |c| c.points.iter().map(|p| p.0).collect());
    let header: String = sizes.iter().map(|n| format!(" N = {n} |")).collect();
    let rule: String = sizes.iter().map(|_| "---|").collect();
    let position = |e: &eitskin::learn::Errors| Some(e.mean_position * 1e3);
    let force = |e: &eitskin::learn::Errors| e.force_rms.map(|f| 100.0 * f / learning.max_force);
    let tables: [(&str, &Reading<'_>); 2] =
        [("Mean position error, mm", &position), ("Force RMS, % of the largest force", &force)];
    for (title, value) in tables {
        s += &format!("{title}:\n\n| method |{header}\n|---|{rule}\n");
        for c in &learning.curves {
            let cells: String = c
                .points
                .iter()
                .map(|(_, e)| match e.as_ref().and_then(value) {
                    Some(v) => format!(" {v:.1} |"),
                    None => " – |".into(),
                })
                .collect();
            s += &format!("| {} |{cells}\n", c.method.name());
        }
        s += "\n";
    }
    s
}

/// The section calibrated as users calibrate, as JSON: one object per row.
pub fn users_json(users: &UsersReport) -> Value {
    let number = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    Value::Array(
        users
            .rows
            .iter()
            .map(|r| {
                json!({
                    "kind": r.kind,
                    "noise": r.noise,
                    "calibrated": r.calibrated,
                    "strength": r.strength.name(),
                    "strength_chosen": r.chosen,
                    "grid": r.grid,
                    "refused": r.refused,
                    "calibration_found": number(r.calibration_found),
                    "single_found": number(r.single_found),
                    "single_rms_newton": number(r.single_rms),
                    "single_within_2_std": number(r.single_within),
                    "pair_found": number(r.pair_found),
                    "pair_rms_newton": number(r.pair_rms),
                    "pair_within_2_std": number(r.pair_within),
                })
            })
            .collect(),
    )
}

/// The section calibrated as users calibrate, as Markdown.
pub fn users_markdown(users: &UsersReport, params: &UsersParams) -> String {
    let mut s = String::from("\n## Calibrated as users calibrate\n\n");
    s += &format!(
        "Presses of kinds the press model does not assume, on the virtual sensor's finer mesh. Calibrated by the paper's protocol (the six unit centres of the lower-left 3×3 units, 0–15 N in 1 N steps, one frame each) or by {} random robot presses (0.5–16 N, one frame each), with a reference of {} frames at rest; validated on {} single presses of 0.5–16 N at random places outside the calibrated units and {} frames of two presses of 2–16 N at least {:.0} mm apart, through the path `eitskin calibrate`, `evaluate` and `run --fresh-presses` take (the pipeline: measured noise, presses found in Δv, forces as their posterior's mean). Found: share of presses of {} N and more with a touch within 20 mm; force RMS in % of {:.0} N over the presses found; within 2σ: share whose truth lies within twice the force's standard deviation. The frames are in `users/`.\n\n",
        params.robot,
        params.reference_frames,
        params.validation,
        params.pairs,
        PAIR_APART * 1e3,
        COUNTED_FROM,
        MAX_FORCE
    );
    s += "| kind | noise | calibrated by | method | single: found | force RMS | within 2σ | pairs: found | force RMS | within 2σ |\n|---|---|---|---|---|---|---|---|---|---|\n";
    let pct = |v: f64| if v.is_finite() { format!("{:.1} %", 100.0 * v) } else { "–".into() };
    let force = |v: f64| if v.is_finite() { format!("{:.1} %", 100.0 * v / MAX_FORCE) } else { "–".into() };
    for r in &users.rows {
        let method = format!(
            "{}{}, {}",
            if r.chosen { "auto: " } else { "" },
            r.strength.name(),
            if r.grid == 1 { "one curve".into() } else { format!("{0}×{0}", r.grid) }
        );
        let cells = match &r.refused {
            Some(reason) => format!("refused: {reason} | | | | | |"),
            None => format!(
                "{} | {} | {} | {} | {} | {} |",
                pct(r.single_found),
                force(r.single_rms),
                pct(r.single_within),
                pct(r.pair_found),
                force(r.pair_rms),
                pct(r.pair_within)
            ),
        };
        s += &format!("| {} | {} % | {} | {method} | {cells}\n", r.kind, 100.0 * r.noise, r.calibrated);
    }
    s
}
