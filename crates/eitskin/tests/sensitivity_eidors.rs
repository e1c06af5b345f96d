//! The peak-versus-position profile of eitskin's own chain (own mesh, truth simulated
//! on a finer mesh) has the shape of EIDORS' (`peaks_two_terminal.csv`) within 15 %.

use eitskin::sensitivity::{along_x, peaks};
use eitskin::{LengthUnit, Reconstructor, ReconstructorParams, SensorSpec};

#[test]
fn peak_profile_has_the_shape_of_eidors() {
    let csv = eitskin_testdata::read_reference("eidors/peaks_two_terminal.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').map(str::trim).collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} in {header:?}"));
    let (xc, yc, peak) = (col("xc"), col("yc"), col("peak_abs"));
    let reference: Vec<(f64, f64)> = lines
        .map(|l| l.split(',').map(|f| f.trim().parse::<f64>().unwrap()).collect::<Vec<_>>())
        .filter(|r| r[yc] == 0.0)
        .map(|r| (r[xc], r[peak]))
        .collect();
    assert_eq!(reference.len(), 17);

    // EIDORS' square: 2 m side, 0.2 m electrodes, z = 0.01 Ω·m², unit depth.
    let mut spec = SensorSpec::square_hydrogel();
    spec.length_unit = LengthUnit::Metre;
    spec.outline = eitskin::Outline::Rectangle { width: 2.0, height: 2.0 };
    spec.thickness = 1.0;
    spec.electrodes.width = 0.2;
    spec.electrodes.contact_impedance = 0.01;
    let model = spec.forward_model().unwrap();
    let mut fine = spec.clone();
    fine.mesh.triangles = 16000;
    let truth = fine.forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let ours = peaks(&truth, 1.0, &recon, &along_x(1.0, 0.1, 0.1, 0.5, 0.05)).unwrap();
    assert_eq!(ours.len(), 17);

    let centre = |p: &[f64]| p[8];
    let theirs: Vec<f64> = reference.iter().map(|r| r.1).collect();
    let mut worst = 0.0f64;
    for (k, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        let (a, b) = (a / centre(&ours), b / centre(&theirs));
        eprintln!("x = {:+.1}: ours {a:.3}, EIDORS {b:.3}", reference[k].0);
        worst = worst.max((a - b).abs() / b);
    }
    eprintln!("edge-to-centre ratio: ours {:.2}, EIDORS {:.2}", ours[0] / centre(&ours), theirs[0] / centre(&theirs));
    assert!(worst < 0.15, "profile shapes differ by {:.1} %", worst * 100.0);
}
