use eitskin::study::sweep::{run, Level, SweepParams};
use eitskin::SensorSpec;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let db: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(66.0);
    let avg: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(1);
    let scale: usize = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(1);
    let params = SweepParams {
        levels: vec![Level { db, average: avg }],
        scenes: [30 * scale, 15 * scale, 15 * scale],
        untouched: 300,
        ..SweepParams::default()
    };
    let t = std::time::Instant::now();
    let report = run(&SensorSpec::square_hydrogel(), &params, &mut |_, _, _| {}).unwrap();
    println!("{:?}", t.elapsed());
    for r in &report.rows {
        println!(
            "{:>14} {:<34} {} found {:5.1}% false/1000 {:6.1} pos {:4.1} mm force {:5.1}%",
            r.method,
            r.kind,
            r.presses,
            100.0 * r.detection,
            r.false_per_1000,
            1e3 * r.position_error,
            100.0 * r.force_rms / report.max_force
        );
    }
}
