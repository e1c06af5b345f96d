//! The mesher returns on any outline a spec can hold: random polygons and degenerate ones (NaN,
//! infinite, huge and tiny coordinates, repeated points, collinear runs, a corner almost on a
//! far edge), with random electrode counts, placements and mesh settings. Each case runs on its
//! own thread and must answer, a mesh or an error, within 5 s (a NaN corner once sent the
//! triangulation into a loop).

use std::sync::mpsc;
use std::time::Duration;

use eitskin::spec::Numbering;
use eitskin::{Outline, Placement, SensorSpec};
use proptest::prelude::*;

/// A coordinate in metres: mostly ordinary, sometimes one a mesher chokes on.
fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -0.2..0.2f64,
        1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300, 1e3, -1e3, 1e-300, 0.0, 1e-12]),
    ]
}

/// A polygon of 3–12 points: random ones (mostly refused: crossing, clockwise, not finite) or
/// a jittered regular one (a valid outline, so that the mesher itself is reached), then bent
/// one of several degenerate ways.
fn polygon() -> impl Strategy<Value = Vec<[f64; 2]>> {
    let random = prop::collection::vec([coordinate(), coordinate()], 3..12);
    let regular = (3..12usize, 1e-3..0.3f64, prop::collection::vec(-0.2..0.2f64, 12)).prop_map(|(n, r, jitter)| {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + jitter[i]) / n as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect::<Vec<_>>()
    });
    let points = prop_oneof![1 => random, 3 => regular];
    (points, 0..4usize, any::<prop::sample::Index>(), coordinate()).prop_map(|(mut points, bend, at, odd)| {
        let n = points.len();
        let k = at.index(n);
        match bend {
            // A repeated point.
            0 => points.insert(k, points[k]),
            // A point on the line between two others.
            1 => {
                let [a, b] = [points[k], points[(k + 1) % n]];
                points.insert(k + 1, [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]);
            }
            // A corner moved to a hair from the middle of a far edge.
            2 if n > 4 => {
                let (a, b) = (points[(k + 2) % n], points[(k + 3) % n]);
                points[k] = [(a[0] + b[0]) / 2.0 * (1.0 - 1e-9), (a[1] + b[1]) / 2.0 * (1.0 - 1e-9)];
            }
            // One coordinate made odd (NaN, infinite, huge, tiny or zero).
            _ => points[k][0] = odd,
        }
        points
    })
}

/// Meshes `spec` on a thread of its own; `None` when it has not answered after 5 s.
fn mesh_within_five_seconds(spec: SensorSpec) -> Option<Result<usize, String>> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let answer = spec.mesh().map(|m| m.triangles().len()).map_err(|e| e.to_string());
        let _ = tx.send(answer);
    });
    rx.recv_timeout(Duration::from_secs(5)).ok()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, max_shrink_iters: 0, ..ProptestConfig::default() })]

    #[test]
    fn the_mesher_answers_every_outline(
        points in polygon(),
        count in 2..33usize,
        start in -400.0..400.0f64,
        explicit in any::<bool>(),
        triangles in 1..6000usize,
        grading in prop_oneof![4 => 1e-3..1.0f64, 1 => -1.0..2.0f64],
        min_angle in prop_oneof![4 => 1.0..33.0f64, 1 => -10.0..60.0f64],
    ) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.electrodes.count = count;
        spec.electrodes.numbering = Numbering::CounterClockwise;
        spec.electrodes.placement = if explicit {
            Placement::Explicit { positions: points.iter().cycle().take(count).copied().collect() }
        } else {
            Placement::Equal { start_angle_deg: start }
        };
        spec.outline = Outline::Polygon { points: points.clone() };
        spec.mesh.triangles = triangles;
        spec.mesh.grading = grading;
        spec.mesh.min_angle_deg = min_angle;
        let answer = mesh_within_five_seconds(spec);
        prop_assert!(answer.is_some(), "no answer after 5 s: {points:?}, {count} electrodes");
        if let Some(Err(message)) = answer {
            prop_assert!(!message.contains("::") && !message.contains(" { "), "{message}");
        }
    }
}
