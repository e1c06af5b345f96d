//! The press-model cache: a built [`PressModel`] (its response table and ladder, seconds of
//! forward solves) saved to a file named by a hash of the spec, protocol, mesh settings, the
//! model's parameters and this crate's version, so a second start loads it (and factors the
//! forward model again for the exact responses, [`PressModel::with_exact`]).
//!
//! File layout (little-endian): `EITSKINP`, format version (u32), the 32-byte key, lo (2 × f64),
//! spacing (f64), dims (2 × u32), measurements (u32), radius, search (f64), the responses
//! (points × measurements f64), coarse spacing (f64), coarse dims (2 × u32), the ladder
//! (coarse points × 9 f64). A file that does not match is rebuilt.

use std::path::{Path, PathBuf};

use eitskin::press_fit::{exact_model_for, PressModel, PressModelParams, PressTable};
use eitskin::SensorSpec;

use crate::reconstructor_file::{cache_file, cached, key_of, Reader};
use crate::Error;

const MAGIC: &[u8; 8] = b"EITSKINP";
const FORMAT: u32 = 1;

/// The file a press model for `spec` and `params` is cached in, under `dir`.
pub fn press_model_path(dir: &Path, spec: &SensorSpec, params: &PressModelParams) -> Result<PathBuf, Error> {
    Ok(cache_file(dir, "press-model", &press_model_key(spec, params)?))
}

fn press_model_key(spec: &SensorSpec, params: &PressModelParams) -> Result<[u8; 32], Error> {
    key_of(spec, &format!("press model {params:?}"))
}

/// The cached press model if `dir` holds a valid one, else builds it, saves it (best effort)
/// and returns it; the flag says whether it came from the cache.
pub fn load_or_build_press_model(
    dir: &Path,
    spec: &SensorSpec,
    params: &PressModelParams,
) -> Result<(PressModel, bool), Error> {
    let key = press_model_key(spec, params)?;
    let build = || build_press_model(spec, params);
    let (press_model, hit) =
        cached(&cache_file(dir, "press-model", &key), &key, decode_press_model, build, encode_press_model)?;
    // The table is cached; the exact responses are one factorisation, made again.
    let press_model = match hit {
        true => {
            let model = spec.forward_model()?;
            let values =
                model.measure(&spec.homogeneous(model.mesh())).map_err(eitskin::inverse::InverseError::from)?;
            let exact = exact_model_for(spec, &model)?;
            press_model.with_exact(exact.as_ref().unwrap_or(&model), spec.conductivity, &values)?
        }
        false => press_model,
    };
    Ok((press_model, hit))
}

/// The press model of `spec`, its exact responses on [`exact_model_for`]'s mesh when the spec's
/// own is too fine to keep its inverse whole.
pub fn build_press_model(spec: &SensorSpec, params: &PressModelParams) -> Result<PressModel, Error> {
    let model = spec.forward_model()?;
    let exact = exact_model_for(spec, &model)?;
    Ok(PressModel::with_exact_model(&model, exact.as_ref().unwrap_or(&model), spec.conductivity, params)?)
}

/// The bytes of a cache file.
pub fn encode_press_model(model: &PressModel, key: &[u8; 32]) -> Vec<u8> {
    let t = model.table();
    let mut out = Vec::with_capacity(256 + 8 * (t.responses.len() + 9 * t.ladder.len()));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT.to_le_bytes());
    out.extend_from_slice(key);
    let f64s = |out: &mut Vec<u8>, xs: &[f64]| xs.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
    let u32s =
        |out: &mut Vec<u8>, ns: &[usize]| ns.iter().for_each(|&n| out.extend_from_slice(&(n as u32).to_le_bytes()));
    f64s(&mut out, &[t.lo[0], t.lo[1], t.spacing]);
    u32s(&mut out, &[t.dims[0], t.dims[1], t.measurements]);
    f64s(&mut out, &[t.radius, t.search]);
    f64s(&mut out, &t.responses);
    f64s(&mut out, &[t.coarse_spacing]);
    u32s(&mut out, &t.coarse_dims);
    t.ladder.iter().for_each(|rungs| f64s(&mut out, rungs));
    out
}

/// A press model from cache bytes, or `None` if they are not a complete file for `key`.
pub fn decode_press_model(bytes: &[u8], key: &[u8; 32]) -> Option<PressModel> {
    let mut r = Reader(bytes);
    if r.take(8)? != MAGIC || r.u32()? != FORMAT || r.take(32)? != key {
        return None;
    }
    let (lo, spacing) = ([r.f64()?, r.f64()?], r.f64()?);
    let (dims, measurements) = ([r.u32()? as usize, r.u32()? as usize], r.u32()? as usize);
    let (radius, search) = (r.f64()?, r.f64()?);
    let values = dims[0].checked_mul(dims[1])?.checked_mul(measurements)?;
    let responses = r.f64s(values)?;
    let coarse_spacing = r.f64()?;
    let coarse_dims = [r.u32()? as usize, r.u32()? as usize];
    let rungs = r.f64s(coarse_dims[0].checked_mul(coarse_dims[1])?.checked_mul(9)?)?;
    if !r.0.is_empty() {
        return None;
    }
    let ladder = rungs.chunks_exact(9).map(|c| std::array::from_fn(|k| c[k])).collect();
    let table =
        PressTable { lo, spacing, dims, measurements, radius, search, responses, coarse_spacing, coarse_dims, ladder };
    PressModel::from_table(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_press_model_loads_back_and_a_torn_one_is_rebuilt() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let params = PressModelParams::default();
        let folder = tempfile::Builder::new().prefix("eitskin-press-cache-").tempdir().unwrap();
        let dir = folder.path().join("cache"); // made by the first save, as a user's cache folder is
        let (built, hit) = load_or_build_press_model(&dir, &spec, &params).unwrap();
        assert!(!hit);
        let (loaded, hit) = load_or_build_press_model(&dir, &spec, &params).unwrap();
        assert!(hit, "the second start must come from the cache");
        assert_eq!(loaded.table().responses, built.table().responses);
        assert!(loaded.exact().is_some(), "a loaded model fits presses exactly too");
        let dv: Vec<f64> = built.table().responses[..120].to_vec();
        assert_eq!(loaded.fit(&dv, [0.0, 0.0]), built.fit(&dv, [0.0, 0.0]));

        let path = press_model_path(&dir, &spec, &params).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        let (_, hit) = load_or_build_press_model(&dir, &spec, &params).unwrap();
        assert!(!hit, "a torn file is rebuilt");
        let other = PressModelParams { radius: 0.005, ..params };
        assert_ne!(press_model_path(&dir, &spec, &params).unwrap(), press_model_path(&dir, &spec, &other).unwrap());
    }
}
