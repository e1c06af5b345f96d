//! Does the automatic hyperparameter (the larger of the noise figure's λ and the MAP λ of the
//! measured noise level) work on channel sets from 120 to 2,350, compared with the best of a
//! fixed grid of λ?
//!
//! The design is fixed before any run, and is the same for every sensor:
//!
//! - sensors: the paper's 200 mm square, 16 electrodes, `two-terminal` (120 channels); a disk of
//!   radius 100 mm with 16 electrodes `adjacent` (208) and `opposite` (192), 32 electrodes
//!   `adjacent` and `skip-4` (928 each), 50 electrodes `adjacent` (2,350). Electrodes are
//!   10 mm wide, or half their pitch where that is less; the reconstruction mesh has about
//!   2,000 triangles, the virtual sensor its own mesh three times finer (no inverse crime);
//! - noise: 0.1 % and 0.5 % of each value, independent per frame;
//! - frames: 20 reference frames, then 12 presses of 10 N, one at a time, one single frame
//!   each; the positions are drawn uniformly (seed 2024, the same for every sensor of one
//!   outline) inside the outline and at least 10 mm from its edge;
//! - images: absolute differences against the mean of the references, NOSER prior, channels
//!   weighted by the noise variance measured per channel from the references; λ = auto
//!   (`Reconstructor::with_auto_hyperparameter`) and λ from a fixed grid with the same weights;
//! - touches: `TouchParams::default()` (60 % of the peak);
//! - score of one λ: median distance from each press to the strongest touch (mm; no touch
//!   counts as infinitely far), and hits: presses with exactly one touch, within 15 mm of the
//!   press. The best fixed λ has the most hits, then the smaller median error.
//!
//! Run with `cargo run --release -p eitskin --example hyperparameter_sweep`: about a minute on
//! two busy cores (56 s, most of it the 50-electrode sensor's 2,350-channel systems).

use std::error::Error;
use std::time::Instant;

use eitskin::inverse::{mean_frame, noise_variance, Channels};
use eitskin::sim::{SimParams, VirtualSensor};
use eitskin::touch::detect;
use eitskin::SeededRng;
use eitskin::{Outline, Placement, ProtocolSpec, Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
use rand::{RngExt, SeedableRng};

/// The fixed λ values compared with auto (dimensionless).
const GRID: [f64; 8] = [0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0];
/// Relative noise per value and frame.
const NOISE_LEVELS: [f64; 2] = [0.001, 0.005];
/// Reference frames averaged (and whose spread gives the noise variance).
const REFERENCE_FRAMES: usize = 20;
/// Presses per sensor, one single frame each.
const PRESSES: usize = 12;
/// Force of each press, in N.
const FORCE: f64 = 10.0;
/// No press centre nearer the edge than this, in m.
const EDGE_MARGIN: f64 = 0.010;
/// A hit: exactly one touch, its centre within this of the press, in m.
const HIT_RADIUS: f64 = 0.015;
/// Triangles of the reconstruction mesh (the virtual sensor's is three times finer).
const TRIANGLES: usize = 2000;
/// Seed of the press positions.
const PRESS_SEED: u64 = 2024;
/// Seed of the noise.
const NOISE_SEED: u64 = 7;

/// One sensor of the sweep: a name, its spec.
struct Case {
    name: String,
    spec: SensorSpec,
}

/// The paper's square, 16 electrodes, two-terminal.
fn square() -> Case {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = TRIANGLES;
    Case { name: "square 200 mm, 16 el, two-terminal".into(), spec }
}

/// A disk of radius 100 mm with `count` equally spaced electrodes and this protocol.
fn disk(count: usize, protocol: &str) -> Result<Case, Box<dyn Error>> {
    let radius = 0.100;
    let mut spec = SensorSpec::square_hydrogel();
    spec.outline = Outline::Circle { radius };
    spec.electrodes.count = count;
    let pitch = 2.0 * std::f64::consts::PI * radius / count as f64;
    spec.electrodes.width = (0.5 * pitch).min(0.010);
    spec.electrodes.placement = Placement::Equal { start_angle_deg: 0.0 };
    spec.protocol = ProtocolSpec::from_name(protocol).ok_or_else(|| format!("no protocol \"{protocol}\""))?;
    spec.mesh.triangles = TRIANGLES;
    spec.validate()?;
    Ok(Case { name: format!("disk r 100 mm, {count} el, {protocol}"), spec })
}

/// `count` press centres, uniform inside `outline` and at least [`EDGE_MARGIN`] from its edge, in m.
fn press_positions(outline: &Outline, count: usize) -> Vec<[f64; 2]> {
    let [lo, hi] = outline.bounds();
    let mut rng = SeededRng::seed_from_u64(PRESS_SEED);
    let mut positions = Vec::with_capacity(count);
    while positions.len() < count {
        let p = [rng.random_range(lo[0]..hi[0]), rng.random_range(lo[1]..hi[1])];
        if outline.contains(p) && outline.locate(p).1 >= EDGE_MARGIN {
            positions.push(p);
        }
    }
    positions
}

/// The frames of one sensor at one noise level: the references, and one frame per press.
struct Frames {
    references: Vec<Vec<f64>>,
    pressed: Vec<Vec<f64>>,
}

fn simulate(spec: &SensorSpec, noise: f64, positions: &[[f64; 2]]) -> Result<Frames, Box<dyn Error>> {
    let params = SimParams { noise_relative: noise, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(spec, params, NOISE_SEED)?;
    let references = (0..REFERENCE_FRAMES).map(|_| skin.frame()).collect::<Result<Vec<_>, _>>()?;
    let mut pressed = Vec::with_capacity(positions.len());
    for &position in positions {
        skin.press(position, FORCE);
        pressed.push(skin.frame()?);
        skin.release();
    }
    Ok(Frames { references, pressed })
}

/// How one λ did over the presses.
#[derive(Debug, Clone, Copy)]
struct Score {
    /// Median distance from press to the strongest touch, in m (∞ if most found none).
    median_error: f64,
    /// Presses with exactly one touch within [`HIT_RADIUS`].
    hits: usize,
}

impl Score {
    /// Better: more hits, then a smaller median error.
    fn better_than(&self, other: &Score) -> bool {
        (self.hits, -self.median_error) > (other.hits, -other.median_error)
    }
}

fn score(recon: &Reconstructor, frames: &Frames, positions: &[[f64; 2]]) -> Result<Score, Box<dyn Error>> {
    let v_ref = mean_frame(&frames.references);
    let params = TouchParams::default();
    let mut errors = Vec::with_capacity(positions.len());
    let mut hits = 0;
    for (v, press) in frames.pressed.iter().zip(positions) {
        let touches = detect(&recon.image(&v_ref, v)?, &params);
        let distance = |centre: [f64; 2]| (centre[0] - press[0]).hypot(centre[1] - press[1]);
        let error = touches.first().map_or(f64::INFINITY, |t| distance(t.centre));
        if touches.len() == 1 && error <= HIT_RADIUS {
            hits += 1;
        }
        errors.push(error);
    }
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let median_error = if n % 2 == 1 { errors[n / 2] } else { 0.5 * (errors[n / 2 - 1] + errors[n / 2]) };
    Ok(Score { median_error, hits })
}

/// One row of the results: a sensor at a noise level.
struct Row {
    name: String,
    channels: usize,
    noise: f64,
    auto_lambda: f64,
    auto: Score,
    grid: Vec<Score>,
}

fn run_case(case: &Case) -> Result<Vec<Row>, Box<dyn Error>> {
    let model = case.spec.forward_model()?;
    let recon = Reconstructor::new(&model, case.spec.conductivity, &ReconstructorParams::default())?;
    let channels = recon.measurements();
    let positions = press_positions(&case.spec.outline, PRESSES);
    let mut rows = Vec::new();
    for noise in NOISE_LEVELS {
        let frames = simulate(&case.spec, noise, &positions)?;
        let variance = noise_variance(&frames.references).ok_or("the references do not vary")?;
        let (auto_recon, auto_lambda) =
            recon.with_auto_hyperparameter(Channels::all(channels), Some(variance.clone()))?;
        let auto = score(&auto_recon, &frames, &positions)?;
        // The fixed grid gets the weights auto uses: the relative noise in the model's units.
        let in_volts = variance.iter().zip(recon.linearisation().background()).map(|(r, v)| r * v * v).collect();
        let weighted = Channels::all(channels).with_variance(in_volts);
        let grid = GRID
            .iter()
            .map(|&lambda| score(&recon.derive(lambda, weighted.clone())?, &frames, &positions))
            .collect::<Result<Vec<_>, _>>()?;
        rows.push(Row { name: case.name.clone(), channels, noise, auto_lambda, auto, grid });
    }
    Ok(rows)
}

fn millimetres(error: f64) -> String {
    if error.is_finite() {
        format!("{:.1}", 1e3 * error)
    } else {
        "none".into()
    }
}

fn print_summary(rows: &[Row]) {
    println!(
        "\n{:<36} {:>5} {:>6} {:>8} | {:>9} {:>7} | {:>8} {:>9} {:>7} | {:>8} {:>9}",
        "sensor",
        "ch",
        "noise",
        "λ_auto",
        "auto hits",
        "med mm",
        "best λ",
        "best hits",
        "med mm",
        "hit gap",
        "med ratio"
    );
    for row in rows {
        let (best_index, best) =
            row.grid
                .iter()
                .enumerate()
                .fold((0, row.grid[0]), |b, (i, s)| if s.better_than(&b.1) { (i, *s) } else { b });
        let ratio = row.auto.median_error / best.median_error;
        let ratio = if ratio.is_finite() { format!("{ratio:.2}") } else { "-".into() };
        println!(
            "{:<36} {:>5} {:>5.1}% {:>8.4} | {:>6}/{:<2} {:>7} | {:>8} {:>6}/{:<2} {:>7} | {:>8} {:>9}",
            row.name,
            row.channels,
            100.0 * row.noise,
            row.auto_lambda,
            row.auto.hits,
            PRESSES,
            millimetres(row.auto.median_error),
            GRID[best_index],
            best.hits,
            PRESSES,
            millimetres(best.median_error),
            best.hits as i64 - row.auto.hits as i64,
            ratio
        );
    }
}

fn print_grid(rows: &[Row]) {
    println!("\nhits/{PRESSES} and median error (mm) at each fixed λ, and auto:");
    let header: Vec<String> = GRID.iter().map(|l| format!("{l:>11}")).collect();
    println!("{:<36} {:>6} {} {:>11}", "sensor", "noise", header.join(""), "auto");
    for row in rows {
        let cell = |s: &Score| format!("{:>11}", format!("{:>2} {:>5}", s.hits, millimetres(s.median_error)));
        let cells: Vec<String> = row.grid.iter().map(cell).collect();
        println!("{:<36} {:>5.1}% {} {}", row.name, 100.0 * row.noise, cells.join(""), cell(&row.auto));
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    let start = Instant::now();
    let cases = vec![
        square(),
        disk(16, "adjacent")?,
        disk(16, "opposite")?,
        disk(32, "adjacent")?,
        disk(32, "skip-4")?,
        disk(50, "adjacent")?,
    ];
    let mut rows = Vec::new();
    for case in &cases {
        let case_start = Instant::now();
        rows.extend(run_case(case)?);
        eprintln!("{}: {:.1} s", case.name, case_start.elapsed().as_secs_f64());
    }
    print_summary(&rows);
    print_grid(&rows);
    println!(
        "\n{PRESSES} presses of {FORCE} N per sensor, one frame each; {REFERENCE_FRAMES} reference frames; \
         hit = one touch within {} mm; {:.0} s in all.",
        1e3 * HIT_RADIUS,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
