//! Frames from MAT (v5, v7.3) and NPY files written by independent writers (scipy, h5py, numpy:
//! `tests/fixtures/make_fixtures.py`, whose values are restated here), and rasters written as
//! data and read back with `npyz`.

use std::path::{Path, PathBuf};

use eitskin::{Image, LengthUnit, Mesh};
use eitskin_io::{
    read_frames, read_one_frame, write_elements_csv, write_labels_npy, write_raster_csv, write_raster_npy,
    ArrayProblem, Error, FrameLayout, FrameSelect, FrameTable,
};

const NAN: f64 = f64::NAN;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(name)
}

fn select(variable: Option<&str>, layout: FrameLayout) -> FrameSelect {
    FrameSelect { variable: variable.map(str::to_string), layout }
}

fn read(name: &str, variable: Option<&str>, layout: FrameLayout) -> FrameTable {
    read_frames(&fixture(name), &select(variable, layout)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn problem(name: &str, variable: Option<&str>, layout: FrameLayout) -> (Error, ArrayProblem) {
    match read_frames(&fixture(name), &select(variable, layout)) {
        Err(e @ Error::Array { .. }) => {
            let Error::Array { problem, .. } = &e else { unreachable!() };
            let problem = problem.clone();
            (e, problem)
        }
        other => panic!("{name}: expected an array error, got {other:?}"),
    }
}

/// Frames equal value for value, NaN equal to NaN (a missing channel stays missing).
fn assert_frames(got: &[Vec<f64>], want: &[Vec<f64>]) {
    let same = got.len() == want.len()
        && got
            .iter()
            .zip(want)
            .all(|(g, w)| g.len() == w.len() && g.iter().zip(w).all(|(a, b)| a == b || (a.is_nan() && b.is_nan())));
    assert!(same, "got {got:?}, want {want:?}");
}

/// `vv` of make_fixtures.py: MATLAB's [1 4; NaN 5; 3 6], one frame per column.
fn vv_columns() -> Vec<Vec<f64>> {
    vec![vec![1.0, NAN, 3.0], vec![4.0, 5.0, 6.0]]
}

#[test]
fn mat_v5_doubles_are_frames_per_column_with_nan_passed_through() {
    for name in ["double.mat", "double_compressed.mat"] {
        let table = read(name, None, FrameLayout::Auto);
        assert_frames(&table.frames, &vv_columns());
        assert!(table.imaginary.is_none());
        let rows = read(name, Some("vv"), FrameLayout::Rows);
        assert_frames(&rows.frames, &[vec![1.0, 4.0], vec![NAN, 5.0], vec![3.0, 6.0]]);
    }
}

#[test]
fn mat_v5_single_int16_and_complex_read_as_numbers() {
    // A 1×4 single is a vector: one frame under Auto, four of one value when rows are asked for.
    assert_frames(&read("single_row.mat", None, FrameLayout::Auto).frames, &[vec![0.5, 1.5, -2.0, 3.0]]);
    assert_eq!(read("single_row.mat", None, FrameLayout::Columns).frames.len(), 4);
    assert_frames(
        &read("int16.mat", None, FrameLayout::Auto).frames,
        &[vec![1.0, 400.0], vec![-2.0, 5.0], vec![3.0, -600.0]],
    );
    let z = read("complex.mat", None, FrameLayout::Auto);
    assert_frames(&z.frames, &[vec![1.0, 3.0, -0.5]]);
    assert_frames(z.imaginary.as_deref().unwrap(), &[vec![2.0, -4.0, 0.25]]);
}

#[test]
fn mat_v5_with_two_variables_takes_the_one_named_and_lists_them_otherwise() {
    assert_frames(&read("two_variables.mat", Some("vi"), FrameLayout::Auto).frames, &[vec![1.5, 3.5], vec![2.5, 4.5]]);
    let (e, p) = problem("two_variables.mat", None, FrameLayout::Auto);
    let ArrayProblem::Variable { wanted: None, found } = p else { panic!("{p:?}") };
    let names: Vec<&str> = found.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["vh", "vi"], "the char variable `label` is not numeric");
    let message = e.to_string();
    for part in ["two_variables.mat", "vh (2×2 double)", "vi (2×2 double)", "--select NAME"] {
        assert!(message.contains(part), "{message:?} lacks {part:?}");
    }
    let (e, p) = problem("two_variables.mat", Some("nope"), FrameLayout::Auto);
    assert!(matches!(p, ArrayProblem::Variable { wanted: Some(ref w), .. } if w == "nope"));
    assert!(e.to_string().contains("variable `nope`: has no such numeric variable; it holds vh"), "{e}");
}

#[test]
fn mat_v5_structs_are_refused_with_a_way_out() {
    let (e, p) = problem("struct.mat", Some("data.Uel"), FrameLayout::Auto);
    assert_eq!(p, ArrayProblem::StructField);
    assert!(e.to_string().contains("-v7.3"), "{e}");
    let (_, p) = problem("struct.mat", None, FrameLayout::Auto);
    assert_eq!(p, ArrayProblem::Variable { wanted: None, found: vec![] });
}

#[test]
fn mat_v73_reads_doubles_complex_integers_and_struct_fields() {
    assert_frames(&read("v73.mat", Some("vv"), FrameLayout::Auto).frames, &vv_columns());
    let z = read("v73.mat", Some("z"), FrameLayout::Auto);
    assert_frames(&z.frames, &[vec![1.0, 3.0, -0.5]]);
    assert_frames(z.imaginary.as_deref().unwrap(), &[vec![2.0, -4.0, 0.25]]);
    assert_frames(
        &read("v73.mat", Some("counts"), FrameLayout::Rows).frames,
        &[vec![1.0, -2.0, 3.0], vec![400.0, 5.0, -600.0]],
    );
    assert_frames(&read("v73.mat", Some("data.Uel"), FrameLayout::Auto).frames, &[vec![1.0, 3.0], vec![2.0, 4.0]]);
    let (e, p) = problem("v73.mat", None, FrameLayout::Auto);
    let ArrayProblem::Variable { found, .. } = p else { panic!("{p:?}") };
    let mut listed: Vec<String> = found.iter().map(ToString::to_string).collect();
    listed.sort();
    assert_eq!(listed, ["counts (2×3 int16)", "data.Uel (2×2 double)", "vv (3×2 double)", "z (3×1 complex double)"]);
    assert!(e.to_string().contains("v73.mat"), "{e}");
}

#[test]
fn npy_reads_c_and_fortran_order_integers_and_complex_frames_per_row() {
    assert_frames(&read("f64_c.npy", None, FrameLayout::Auto).frames, &[vec![1.0, NAN, 3.0], vec![4.0, 5.0, 6.0]]);
    assert_frames(
        &read("f64_c.npy", None, FrameLayout::Columns).frames,
        &[vec![1.0, 4.0], vec![NAN, 5.0], vec![3.0, 6.0]],
    );
    assert_frames(
        &read("f32_fortran.npy", None, FrameLayout::Auto).frames,
        &[vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]],
    );
    assert_frames(&read("i32_1d.npy", None, FrameLayout::Columns).frames, &[vec![7.0, -8.0, 9.0]]);
    assert_frames(&read("u16_big_endian.npy", None, FrameLayout::Auto).frames, &[vec![1.0, 2.0], vec![3.0, 250.0]]);
    let z = read("complex128.npy", None, FrameLayout::Auto);
    assert_frames(&z.frames, &[vec![1.0, 3.0, -0.5]]);
    assert_frames(z.imaginary.as_deref().unwrap(), &[vec![2.0, -4.0, 0.25]]);
    let z = read("complex64_2d.npy", None, FrameLayout::Auto);
    assert_frames(&z.frames, &[vec![1.0, 2.0], vec![0.0, -3.0]]);
    assert_frames(z.imaginary.as_deref().unwrap(), &[vec![1.0, -1.0], vec![0.5, 0.0]]);
}

#[test]
fn npy_shapes_and_names_that_do_not_fit_are_refused_saying_what_is_accepted() {
    let (e, p) = problem("f64_3d.npy", None, FrameLayout::Auto);
    assert_eq!(p, ArrayProblem::Shape { shape: vec![2, 2, 2] });
    assert!(e.to_string().contains("has shape 2×2×2; accepted: a vector"), "{e}");
    let (_, p) = problem("f64_c.npy", Some("vv"), FrameLayout::Auto);
    assert_eq!(p, ArrayProblem::NoVariables { format: "NPY" });
}

#[test]
fn one_frame_is_refused_from_a_table_of_several_or_from_complex_data() {
    let one = read_one_frame(&fixture("single_row.mat"), &FrameSelect::default()).unwrap();
    assert_eq!(one, [0.5, 1.5, -2.0, 3.0]);
    let e = read_one_frame(&fixture("double.mat"), &FrameSelect::default()).unwrap_err();
    assert!(matches!(e, Error::Array { problem: ArrayProblem::FrameCount { frames: 2 }, .. }), "{e}");
    assert!(e.to_string().contains("holds 2 frames where one was expected"), "{e}");
    let e = read_one_frame(&fixture("complex128.npy"), &FrameSelect::default()).unwrap_err();
    assert!(matches!(e, Error::Array { problem: ArrayProblem::Complex, .. }), "{e}");
}

#[test]
fn text_frames_still_read_and_pass_nan_through_here_only() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.csv");
    std::fs::write(&path, "measurement,value_ohm\n1,2.5\n2,NaN\n3,-1\n").unwrap();
    assert_frames(&read_frames(&path, &FrameSelect::default()).unwrap().frames, &[vec![2.5, NAN, -1.0]]);
    assert!(eitskin_io::read_frame(&path).is_err(), "the single-frame reader still refuses NaN");
    std::fs::write(&path, "1, inf").unwrap();
    let e = read_frames(&path, &FrameSelect::default()).unwrap_err();
    assert!(matches!(e, Error::Array { problem: ArrayProblem::NotFinite { frame: 1, channel: 2 }, .. }), "{e}");
}

const FIXTURES: [&str; 15] = [
    "double.mat",
    "double_compressed.mat",
    "single_row.mat",
    "int16.mat",
    "complex.mat",
    "struct.mat",
    "two_variables.mat",
    "v73.mat",
    "f64_c.npy",
    "f32_fortran.npy",
    "complex128.npy",
    "complex64_2d.npy",
    "i32_1d.npy",
    "u16_big_endian.npy",
    "f64_3d.npy",
];

/// Every prefix and every one-byte corruption of every fixture: an answer each time, never a panic.
#[test]
fn truncated_or_corrupted_files_give_errors_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("damaged");
    let selects = [FrameSelect::default(), select(Some("vv"), FrameLayout::Columns)];
    for name in FIXTURES {
        let bytes = std::fs::read(fixture(name)).unwrap();
        for len in 0..bytes.len() {
            std::fs::write(&path, &bytes[..len]).unwrap();
            for s in &selects {
                let _ = read_frames(&path, s);
            }
        }
        // Corrupt each byte (of the first 1024: past them lies only data or HDF5 padding).
        for at in 0..bytes.len().min(1024) {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0xA5;
            std::fs::write(&path, &damaged).unwrap();
            let _ = read_frames(&path, &selects[0]);
        }
    }
    // A cut-off NPY says the data are short; a cut-off MAT v5 file says it is not readable.
    let npy = std::fs::read(fixture("f64_c.npy")).unwrap();
    std::fs::write(&path, &npy[..npy.len() - 3]).unwrap();
    let e = read_frames(&path, &FrameSelect::default()).unwrap_err();
    assert!(matches!(&e, Error::Array { problem: ArrayProblem::Malformed { format: "NPY", .. }, .. }), "{e}");
    let mat = std::fs::read(fixture("double.mat")).unwrap();
    std::fs::write(&path, &mat[..mat.len() - 20]).unwrap();
    let e = read_frames(&path, &FrameSelect::default()).unwrap_err();
    assert!(matches!(&e, Error::Array { .. }), "{e}");
    assert!(e.to_string().starts_with(&path.display().to_string()), "{e}");
}

fn image() -> Image {
    // 3 × 2 pixels over [-3, 3] × [-1, 1] mm; the top-right pixel is outside the sensor.
    let mut image = Image::new([3, 2], [[-0.003, -0.001], [0.003, 0.001]], vec![true, true, false, true, true, true]);
    image.values = vec![0.5, -1.0, 0.0, 2.0, 0.25, -0.125];
    image
}

#[test]
fn a_raster_written_as_npy_reads_back_as_rows_from_the_top_with_nan_outside() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("image.npy");
    write_raster_npy(&path, &image()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), [2, 3]);
    assert_eq!(npy.order(), npyz::Order::C);
    assert_eq!(npy.dtype(), npyz::DType::Plain("<f4".parse().unwrap()));
    let values: Vec<f32> = npy.into_vec().unwrap();
    assert_eq!(values[..2], [0.5, -1.0]);
    assert!(values[2].is_nan());
    assert_eq!(values[3..], [2.0, 0.25, -0.125]);
    // And through the reader of this crate, as numpy would: rows from the top.
    let table = read_frames(&path, &FrameSelect::default()).unwrap();
    assert_frames(&table.frames, &[vec![0.5, -1.0, NAN], vec![2.0, 0.25, -0.125]]);
}

#[test]
fn labels_written_as_npy_read_back_as_uint8_rows() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("labels.npy");
    write_labels_npy(&path, &[0, 1, 1, 0, 2, 0], [3, 2]).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), [2, 3]);
    assert_eq!(npy.into_vec::<u8>().unwrap(), [0, 1, 1, 0, 2, 0]);
}

#[test]
fn raster_csv_lists_inside_pixel_centres_in_the_users_unit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("image.csv");
    write_raster_csv(&path, &image(), LengthUnit::Millimetre).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "x_mm,y_mm,delta_sigma_s_per_m");
    assert_eq!(lines.len(), 1 + 5, "five pixels are inside");
    // Centres: x = -3 + (col + ½)·2 mm, y = 1 − (row + ½)·1 mm.
    let parsed: Vec<[f64; 3]> = lines[1..]
        .iter()
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|f| f.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let want = [[-2.0, 0.5, 0.5], [0.0, 0.5, -1.0], [-2.0, -0.5, 2.0], [0.0, -0.5, 0.25], [2.0, -0.5, -0.125]];
    for (got, want) in parsed.iter().zip(want) {
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12, "{got:?} vs {want:?}");
        }
    }
}

#[test]
fn element_csv_puts_each_value_at_its_triangles_centroid() {
    let mesh = Mesh::new(
        vec![[0.0, 0.0], [0.003, 0.0], [0.0, 0.003], [0.003, 0.003]],
        vec![[0, 1, 2], [1, 3, 2]],
        vec![vec![0], vec![3]],
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("elements.csv");
    write_elements_csv(&path, &mesh, &[0.5, NAN], LengthUnit::Millimetre, "conductivity_s_per_m").unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "triangle,x_mm,y_mm,conductivity_s_per_m");
    let first: Vec<f64> = lines[1].split(',').map(|f| f.parse().unwrap()).collect();
    assert_eq!(first[0], 0.0);
    assert!((first[1] - 1.0).abs() < 1e-12 && (first[2] - 1.0).abs() < 1e-12 && first[3] == 0.5, "{first:?}");
    assert!(lines[2].starts_with("1,2") && lines[2].ends_with(",NaN"), "{}", lines[2]);
}
