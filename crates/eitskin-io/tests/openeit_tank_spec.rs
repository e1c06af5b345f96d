//! The OpenEIT tank spec shipped in `examples/` loads, places electrode 1 at 180° with
//! electrode 2 clockwise of it, and its protocol gives the firmware's 928 values per frame.

use std::path::Path;

use eitskin_io::read_spec;

#[test]
fn openeit_tank_spec_loads_with_928_measurements() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/openeit-tank-32.toml");
    let spec = read_spec(&path).unwrap();
    assert_eq!(spec.electrodes.count, 32);
    assert_eq!(spec.protocol().unwrap().len(), 928, "32 × 29, as the firmware's lookup table");
    let electrodes = spec.electrode_positions().unwrap();
    let at = |k: usize| spec.outline.point_at(electrodes[k].centre);
    let r = 0.1;
    let (first, second) = (at(0), at(1));
    assert!((first[0] + r).abs() < 1e-12 && first[1].abs() < 1e-12, "electrode 1 at {first:?}");
    // pyEIT's fixed points: electrode k at (−r cos t, r sin t), t = 2πk/32.
    let t = 2.0 * std::f64::consts::PI / 32.0;
    assert!((second[0] + r * t.cos()).abs() < 1e-12 && (second[1] - r * t.sin()).abs() < 1e-12, "{second:?}");
}
