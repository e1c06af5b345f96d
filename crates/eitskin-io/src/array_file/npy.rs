//! NPY files (numpy's `np.save`), through the `npyz` crate: float, integer and complex dtypes of
//! either byte order, C or Fortran order.

use npyz::{DType, Deserialize, NpyFile, Order, TypeChar};
use num_complex::Complex;

use super::{Array, ArrayProblem};

const FORMAT: &str = "NPY";

fn malformed(message: impl ToString) -> ArrayProblem {
    ArrayProblem::Malformed { format: FORMAT, message: message.to_string() }
}

/// The one array of an NPY file.
pub(super) fn read(bytes: &[u8]) -> Result<Array, ArrayProblem> {
    let npy = NpyFile::new(bytes).map_err(malformed)?;
    let header = npy.header().clone();
    let shape: Vec<usize> = npy
        .shape()
        .iter()
        .map(|&n| usize::try_from(n))
        .collect::<Result<_, _>>()
        .map_err(|_| malformed("a dimension does not fit in memory"))?;
    let column_major = npy.order() == Order::Fortran;
    let DType::Plain(type_str) = npy.dtype() else {
        return Err(ArrayProblem::ElementType { class: npy.dtype().descr() });
    };
    // The header's shape sizes what npyz allocates: check it against the bytes there are first.
    let count = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
    let needed = count.and_then(|n| n.checked_mul(type_str.num_bytes().unwrap_or(0)));
    let data = npy.into_inner();
    if needed.is_none_or(|needed| needed > data.len()) {
        return Err(malformed(format!(
            "the header announces shape {:?} of {type_str}, {} bytes of data follow",
            shape,
            data.len()
        )));
    }
    let npy = NpyFile::with_header(header, data);
    let (real, imaginary) = match (type_str.type_char(), type_str.size_field()) {
        (TypeChar::Float, 8) => (real::<f64>(npy)?, None),
        (TypeChar::Float, 4) => (real::<f32>(npy)?, None),
        (TypeChar::Int, 1) => (real::<i8>(npy)?, None),
        (TypeChar::Int, 2) => (real::<i16>(npy)?, None),
        (TypeChar::Int, 4) => (real::<i32>(npy)?, None),
        (TypeChar::Int, 8) => (real::<i64>(npy)?, None),
        (TypeChar::Uint, 1) => (real::<u8>(npy)?, None),
        (TypeChar::Uint, 2) => (real::<u16>(npy)?, None),
        (TypeChar::Uint, 4) => (real::<u32>(npy)?, None),
        (TypeChar::Uint, 8) => (real::<u64>(npy)?, None),
        (TypeChar::Complex, 16) => complex::<f64>(npy)?,
        (TypeChar::Complex, 8) => complex::<f32>(npy)?,
        _ => return Err(ArrayProblem::ElementType { class: type_str.to_string() }),
    };
    Ok(Array { shape, column_major, real, imaginary })
}

/// Values of a real dtype as `f64` (64-bit integers beyond 2⁵³ round to the nearest double).
fn real<T: Deserialize + IntoF64>(npy: NpyFile<&[u8]>) -> Result<Vec<f64>, ArrayProblem> {
    Ok(npy.into_vec::<T>().map_err(malformed)?.into_iter().map(IntoF64::into_f64).collect())
}

/// Real and imaginary parts of a complex dtype.
#[allow(clippy::type_complexity)]
fn complex<T: IntoF64 + Copy>(npy: NpyFile<&[u8]>) -> Result<(Vec<f64>, Option<Vec<f64>>), ArrayProblem>
where
    Complex<T>: Deserialize,
{
    let values = npy.into_vec::<Complex<T>>().map_err(malformed)?;
    Ok((values.iter().map(|z| z.re.into_f64()).collect(), Some(values.iter().map(|z| z.im.into_f64()).collect())))
}

/// A number as `f64`: exact for all but 64-bit integers beyond 2⁵³.
trait IntoF64 {
    fn into_f64(self) -> f64;
}

macro_rules! into_f64 {
    ($($t:ty),*) => {$(
        impl IntoF64 for $t {
            fn into_f64(self) -> f64 {
                self as f64
            }
        }
    )*};
}
into_f64!(f64, f32, i8, i16, i32, i64, u8, u16, u32, u64);
