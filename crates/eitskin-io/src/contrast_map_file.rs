//! The contrast-map cache: a built [`ContrastMap`] (thousands of forward solves and images)
//! saved to a file named by a hash of the spec, protocol, mesh settings, the reconstructor's and
//! the map's parameters and this crate's version, so a second start loads it.
//!
//! File layout (little-endian): `EITSKINC`, format version (u32), the 32-byte key, lo
//! (2 × f64), step (2 × f64), points per side (u32), drops (u32 count, then f64 each), then
//! per drop the peaks and per drop the volumes (points² f64 each). A file that does not
//! match is rebuilt.

use std::path::{Path, PathBuf};

use eitskin::contrast_map::{ContrastMap, ContrastMapParams, ContrastTable};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec};

use crate::reconstructor_file::{cache_file, cached, key_of, Reader};
use crate::Error;

const MAGIC: &[u8; 8] = b"EITSKINC";
const FORMAT: u32 = 1;

/// The file a contrast map for `spec`, `recon` and `params` is cached in, under `dir`.
pub fn contrast_map_path(
    dir: &Path,
    spec: &SensorSpec,
    recon: &ReconstructorParams,
    params: &ContrastMapParams,
) -> Result<PathBuf, Error> {
    Ok(cache_file(dir, "contrast-map", &contrast_map_key(spec, recon, params)?))
}

fn contrast_map_key(
    spec: &SensorSpec,
    recon: &ReconstructorParams,
    params: &ContrastMapParams,
) -> Result<[u8; 32], Error> {
    key_of(spec, &format!("contrast map {recon:?} {params:?}"))
}

/// The cached contrast map if `dir` holds a valid one, else builds it through `recon` (the
/// sensor's reconstructor), saves it (best effort) and returns it; the flag says whether it
/// came from the cache.
pub fn load_or_build_contrast_map(
    dir: &Path,
    spec: &SensorSpec,
    recon: &Reconstructor,
    params: &ContrastMapParams,
) -> Result<(ContrastMap, bool), Error> {
    let key = contrast_map_key(spec, recon.params(), params)?;
    let build = || {
        let model = spec.forward_model()?;
        Ok(ContrastMap::new(&model, spec.conductivity, recon, spec.outline.bounds(), params)?)
    };
    cached(&cache_file(dir, "contrast-map", &key), &key, decode_contrast_map, build, encode_contrast_map)
}

/// The bytes of a cache file.
pub fn encode_contrast_map(map: &ContrastMap, key: &[u8; 32]) -> Vec<u8> {
    let t = map.table();
    let mut out = Vec::with_capacity(128 + 16 * t.drops.len() * t.points * t.points);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT.to_le_bytes());
    out.extend_from_slice(key);
    let f64s = |out: &mut Vec<u8>, xs: &[f64]| xs.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
    f64s(&mut out, &[t.lo[0], t.lo[1], t.step[0], t.step[1]]);
    out.extend_from_slice(&(t.points as u32).to_le_bytes());
    out.extend_from_slice(&(t.drops.len() as u32).to_le_bytes());
    f64s(&mut out, &t.drops);
    t.peaks.iter().chain(&t.volumes).for_each(|row| f64s(&mut out, row));
    out
}

/// A contrast map from cache bytes, or `None` if they are not a complete file for `key`.
pub fn decode_contrast_map(bytes: &[u8], key: &[u8; 32]) -> Option<ContrastMap> {
    let mut r = Reader(bytes);
    if r.take(8)? != MAGIC || r.u32()? != FORMAT || r.take(32)? != key {
        return None;
    }
    let (lo, step) = ([r.f64()?, r.f64()?], [r.f64()?, r.f64()?]);
    let (points, count) = (r.u32()? as usize, r.u32()? as usize);
    let drops = r.f64s(count)?;
    let cells = points.checked_mul(points)?;
    let mut rows = || (0..count).map(|_| r.f64s(cells)).collect::<Option<Vec<_>>>();
    let (peaks, volumes) = (rows()?, rows()?);
    if !r.0.is_empty() {
        return None;
    }
    ContrastMap::from_table(ContrastTable { lo, step, points, drops, peaks, volumes })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_contrast_map_loads_back_and_a_torn_one_is_rebuilt() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let recon = ReconstructorParams { raster: [16, 16], ..ReconstructorParams::default() };
        let params = ContrastMapParams { points: 4, ..ContrastMapParams::default() };
        let folder = tempfile::Builder::new().prefix("eitskin-contrast-cache-").tempdir().unwrap();
        let dir = folder.path();
        let reconstructor = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &recon).unwrap();
        let (built, hit) = load_or_build_contrast_map(dir, &spec, &reconstructor, &params).unwrap();
        assert!(!hit);
        let (loaded, hit) = load_or_build_contrast_map(dir, &spec, &reconstructor, &params).unwrap();
        assert!(hit, "the second start must come from the cache");
        assert_eq!(loaded, built);
        let path = contrast_map_path(dir, &spec, &recon, &params).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        assert!(!load_or_build_contrast_map(dir, &spec, &reconstructor, &params).unwrap().1, "a torn file is rebuilt");
        let finer = ContrastMapParams { points: 5, ..params };
        assert_ne!(path, contrast_map_path(dir, &spec, &recon, &finer).unwrap());
    }
}
