//! Clockwise numbering is a relabelling, nothing else: clockwise electrode k (1-based) is the
//! counter-clockwise electrode (2 − k) mod L, in position and in every forward measurement.

use eitskin::spec::Numbering;
use eitskin::{Outline, Placement, Protocol, ProtocolSpec, SensorSpec};

/// A 300 × 200 mm sheet, 16 electrodes equally spaced from 20° (no mirror symmetry maps the
/// layout onto its clockwise relabelling, so a wrong permutation cannot pass by symmetry).
fn sheet(numbering: Numbering, protocol: ProtocolSpec) -> SensorSpec {
    let mut spec = SensorSpec::square_hydrogel();
    spec.outline = Outline::Rectangle { width: 0.3, height: 0.2 };
    spec.electrodes.placement = Placement::Equal { start_angle_deg: 20.0 };
    spec.electrodes.numbering = numbering;
    spec.protocol = protocol;
    spec.mesh.triangles = 1500;
    spec
}

/// 0-based counter-clockwise index of clockwise electrode `k` (0-based): 0 stays, k ↦ L − k.
fn counter_clockwise_index(k: usize, l: usize) -> usize {
    (l - k) % l
}

/// Each measurement as (drive +, drive −, measure +, measure −), 0-based.
fn quads(protocol: &Protocol) -> Vec<[usize; 4]> {
    let find = |values: &[f64], v: f64| values.iter().position(|x| *x == v).unwrap_or(usize::MAX);
    protocol
        .measurements()
        .iter()
        .map(|m| {
            let s = &protocol.stimulations()[m.stimulation];
            [find(s, 1.0), find(s, -1.0), find(&m.weights, 1.0), find(&m.weights, -1.0)]
        })
        .collect()
}

/// The counter-clockwise value of a clockwise quad: its electrodes relabelled, each pair
/// looked up in either polarity (a reversed pair flips the sign).
fn relabelled(cw: &[usize; 4], ccw_quads: &[[usize; 4]], ccw_values: &[f64], l: usize) -> f64 {
    let q = cw.map(|e| counter_clockwise_index(e, l));
    for (row, c) in ccw_quads.iter().enumerate() {
        let drive = if [c[0], c[1]] == [q[0], q[1]] {
            1.0
        } else if [c[1], c[0]] == [q[0], q[1]] {
            -1.0
        } else {
            0.0
        };
        let measure = if [c[2], c[3]] == [q[2], q[3]] {
            1.0
        } else if [c[3], c[2]] == [q[2], q[3]] {
            -1.0
        } else {
            0.0
        };
        if drive * measure != 0.0 {
            return drive * measure * ccw_values[row];
        }
    }
    panic!("quad {cw:?} has no counter-clockwise counterpart")
}

#[test]
fn clockwise_positions_are_the_counter_clockwise_ones_relabelled() {
    let ccw = sheet(Numbering::CounterClockwise, ProtocolSpec::TwoTerminal);
    let cw = sheet(Numbering::Clockwise, ProtocolSpec::TwoTerminal);
    let (a, b) = (ccw.electrode_positions().unwrap(), cw.electrode_positions().unwrap());
    for k in 0..b.len() {
        assert_eq!(b[k], a[counter_clockwise_index(k, a.len())], "electrode {}", k + 1);
    }
}

#[test]
fn clockwise_measurements_are_the_counter_clockwise_ones_relabelled() {
    for protocol in [ProtocolSpec::TwoTerminal, ProtocolSpec::Skip { skip: 2, skip_driven: true }] {
        let (ccw, cw) = (sheet(Numbering::CounterClockwise, protocol.clone()), sheet(Numbering::Clockwise, protocol));
        let ccw_model = ccw.forward_model().unwrap();
        let cw_model = cw.forward_model().unwrap();
        let ccw_values = ccw_model.measure(&ccw.homogeneous(ccw_model.mesh())).unwrap();
        let cw_values = cw_model.measure(&cw.homogeneous(cw_model.mesh())).unwrap();
        let ccw_quads = quads(ccw_model.protocol());
        let scale = ccw_values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (row, q) in quads(cw_model.protocol()).iter().enumerate() {
            let want = relabelled(q, &ccw_quads, &ccw_values, 16);
            // Both meshes are built from the same electrode intervals, so only rounding differs.
            assert!(
                (cw_values[row] - want).abs() <= 1e-9 * scale,
                "{}: row {}: {} vs {want}",
                cw_model.protocol().description(),
                row + 1,
                cw_values[row]
            );
        }
    }
}
