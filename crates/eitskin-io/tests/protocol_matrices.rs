//! Protocols given as a data set's two matrices (currents per stimulation, weights per
//! measurement pattern) in a MAT file, named in the spec: the same protocol as the built-in one
//! they spell, either way round, and a wrong matrix refused with its shape.

use eitskin::Protocol;

/// `adjacent-all` for 16 electrodes, its first `count` stimulations, as a data set ships it:
/// `Inj` (16 × count, one stimulation per column) and `Mpat` (16 × 16, one measurement pattern
/// per column), `Inj` perhaps the other way round; with the protocol they spell.
fn matrices(count: usize, transposed: bool) -> (Vec<Vec<f64>>, Vec<eitskin::Measurement>, Vec<u8>) {
    let builtin = Protocol::adjacent(16, false).unwrap();
    let stimulations = builtin.stimulations()[..count].to_vec();
    let measurements = builtin.measurements()[..16 * count].to_vec();
    let patterns: Vec<Vec<f64>> = measurements[..16].iter().map(|m| m.weights.clone()).collect();
    let flat = |columns: &[Vec<f64>], transposed: bool| -> Vec<f64> {
        if transposed {
            (0..16).flat_map(|i| columns.iter().map(move |c| c[i])).collect() // rows of the transposed
        } else {
            columns.iter().flatten().copied().collect()
        }
    };
    let (inj, mpat) = (flat(&stimulations, transposed), flat(&patterns, false));
    let (r, c) = if transposed { (count, 16) } else { (16, count) };
    let bytes =
        eitskin_testdata::mat5(&[("Inj", r, c, &inj), ("Mpat", 16, 16, &mpat), ("Uelref", 256, 1, &[0.5; 256])]);
    (stimulations, measurements, bytes)
}

/// The paper's sensor with its protocol section replaced by `protocol` (TOML lines).
fn spec_with(protocol: &str) -> String {
    let text = eitskin_io::spec_to_toml(&eitskin::SensorSpec::square_hydrogel());
    text.replace("kind = \"two-terminal\"", protocol)
}

#[test]
fn a_data_sets_pattern_matrices_spell_the_builtin_protocol() {
    let dir = tempfile::tempdir().unwrap();
    // A square matrix is read one pattern per column (MATLAB's habit); a data set with fewer
    // stimulations than electrodes may give them either way round.
    for (count, transposed) in [(16, false), (12, false), (12, true)] {
        let (stimulations, measurements, bytes) = matrices(count, transposed);
        std::fs::write(dir.path().join("ref.mat"), bytes).unwrap();
        let spec = spec_with("kind = \"custom\"\nfile = \"ref.mat\"\nstimulation = \"Inj\"\nmeasurement = \"Mpat\"");
        let spec = eitskin_io::parse_spec(&spec, dir.path()).unwrap();
        let protocol = spec.protocol().unwrap();
        assert_eq!(protocol.stimulations(), stimulations, "{count} stimulations, transposed: {transposed}");
        assert_eq!(protocol.measurements(), measurements, "{count} stimulations, transposed: {transposed}");
        assert_eq!(protocol.description(), "Inj × Mpat from ref.mat");
    }
    let spec = spec_with("kind = \"custom\"\nfile = \"ref.mat\"\nstimulation = \"Uelref\"\nmeasurement = \"Mpat\"");
    let err = eitskin_io::parse_spec(&spec, dir.path()).unwrap_err();
    let message = eitskin_io::full_message(&err);
    assert!(
        message.contains("`Uelref` is a real 256 × 1 matrix; a pattern matrix must be real with one side of 16"),
        "{message}"
    );
    let spec = spec_with("kind = \"custom\"\nfile = \"ref.mat\"\nstimulation = \"Inj\"");
    let err = eitskin_io::parse_spec(&spec, dir.path()).unwrap_err();
    assert!(err.to_string().contains("protocol.measurement"), "{err}");
}
