//! The reconstructor cache: a built [`Reconstructor`] saved to a file named by a hash of
//! everything it depends on (spec, protocol, mesh settings, prior, λ, normalisation, raster,
//! and this crate's version), so a second start loads it instead of rebuilding.
//!
//! File layout (little-endian): `EITSKINR`, format version (u32), the 32-byte key, the
//! parameters (prior tag u8, exponent f64, λ f64, normalised u8), raster nx, ny (u32),
//! bounds (4 × f64), one byte per pixel (inside or not), measurements (u32), then the matrix
//! (pixels × measurements f32, column-major). A file that does not match is rebuilt.

use std::path::{Path, PathBuf};

use eitskin::{Image, Prior, Reconstructor, ReconstructorParams, SensorSpec};
use sha2::{Digest, Sha256};

use crate::Error;

const MAGIC: &[u8; 8] = b"EITSKINR";
const FORMAT: u32 = 1;

/// The cache key: SHA-256 of the spec, protocol patterns, mesh settings and parameters.
pub fn cache_key(spec: &SensorSpec, params: &ReconstructorParams) -> Result<[u8; 32], Error> {
    key_of(spec, &format!("{params:?}"))
}

/// SHA-256 of this crate's version, the spec, its protocol patterns, its mesh settings and `extra`.
pub(crate) fn key_of(spec: &SensorSpec, extra: &str) -> Result<[u8; 32], Error> {
    let mut hash = Sha256::new();
    hash.update(env!("CARGO_PKG_VERSION"));
    hash.update(crate::spec_to_toml(spec));
    // Custom protocols are not in the TOML: hash the patterns themselves.
    hash.update(format!("{:?}", spec.protocol()?));
    hash.update(format!("{:?} {extra}", spec.mesh));
    Ok(hash.finalize().into())
}

/// The file a reconstructor for `spec` and `params` is cached in, under `dir`.
pub fn cache_path(dir: &Path, spec: &SensorSpec, params: &ReconstructorParams) -> Result<PathBuf, Error> {
    Ok(cache_file(dir, "reconstructor", &cache_key(spec, params)?))
}

/// The cached reconstructor if `dir` holds a valid one, else builds it, saves it (best effort)
/// and returns it; the flag says whether it came from the cache.
pub fn load_or_build(
    dir: &Path,
    spec: &SensorSpec,
    params: &ReconstructorParams,
) -> Result<(Reconstructor, bool), Error> {
    let key = cache_key(spec, params)?;
    let build = || {
        let model = spec.forward_model()?;
        Ok(Reconstructor::new(&model, spec.conductivity, params)?)
    };
    cached(&cache_file(dir, "reconstructor", &key), &key, decode_reconstructor, build, encode_reconstructor)
}

/// The cache file `STEM-KEY.bin` under `dir` (the key's first 12 bytes in hex).
pub(crate) fn cache_file(dir: &Path, stem: &str, key: &[u8; 32]) -> PathBuf {
    let hex: String = key[..12].iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("{stem}-{hex}.bin"))
}

/// What `path` holds for `key` if it decodes, else what `build` makes, saved there (best
/// effort); the flag says whether it came from the file.
pub(crate) fn cached<T>(
    path: &Path,
    key: &[u8; 32],
    decode: impl Fn(&[u8], &[u8; 32]) -> Option<T>,
    build: impl FnOnce() -> Result<T, Error>,
    encode: impl Fn(&T, &[u8; 32]) -> Vec<u8>,
) -> Result<(T, bool), Error> {
    if let Some(value) = std::fs::read(path).ok().and_then(|bytes| decode(&bytes, key)) {
        return Ok((value, true));
    }
    let value = build()?;
    // A cache that cannot be written costs time, not correctness.
    let _ =
        path.parent().map_or(Ok(()), std::fs::create_dir_all).and_then(|()| std::fs::write(path, encode(&value, key)));
    Ok((value, false))
}

/// The bytes of a cache file.
pub fn encode_reconstructor(recon: &Reconstructor, key: &[u8; 32]) -> Vec<u8> {
    let p = recon.params();
    let image = recon.blank_image();
    let (tag, exponent) = match p.prior {
        Prior::Noser { exponent } => (0u8, exponent),
        Prior::Tikhonov => (1, 0.0),
        Prior::Laplace => (2, 0.0),
    };
    let mut out = Vec::with_capacity(128 + image.inside.len() + 4 * recon.matrix().len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT.to_le_bytes());
    out.extend_from_slice(key);
    out.push(tag);
    out.extend_from_slice(&exponent.to_le_bytes());
    out.extend_from_slice(&p.hyperparameter.to_le_bytes());
    out.push(u8::from(p.normalized));
    for n in image.size {
        out.extend_from_slice(&(n as u32).to_le_bytes());
    }
    for c in image.bounds.iter().flatten() {
        out.extend_from_slice(&c.to_le_bytes());
    }
    out.extend(image.inside.iter().map(|&b| u8::from(b)));
    out.extend_from_slice(&(recon.measurements() as u32).to_le_bytes());
    for x in recon.matrix() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// A reconstructor from cache bytes, or `None` if they are not a complete file for `key`.
pub fn decode_reconstructor(bytes: &[u8], key: &[u8; 32]) -> Option<Reconstructor> {
    let mut r = Reader(bytes);
    if r.take(8)? != MAGIC || r.u32()? != FORMAT || r.take(32)? != key {
        return None;
    }
    let (tag, exponent, hyperparameter, normalized) = (r.take(1)?[0], r.f64()?, r.f64()?, r.take(1)?[0] == 1);
    let prior = match tag {
        0 => Prior::Noser { exponent },
        1 => Prior::Tikhonov,
        2 => Prior::Laplace,
        _ => return None,
    };
    let size = [r.u32()? as usize, r.u32()? as usize];
    let bounds = [[r.f64()?, r.f64()?], [r.f64()?, r.f64()?]];
    let pixels = size[0].checked_mul(size[1])?;
    let inside = r.take(pixels)?.iter().map(|&b| b == 1).collect();
    let measurements = r.u32()? as usize;
    let raw = r.take(pixels.checked_mul(measurements)?.checked_mul(4)?)?;
    if !r.0.is_empty() {
        return None;
    }
    let matrix = raw.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let params = ReconstructorParams { prior, hyperparameter, normalized, raster: size };
    Reconstructor::from_parts(params, Image::new(size, bounds, inside), matrix)
}

/// Reads little-endian values off the front of a byte slice; `None` once it runs out.
pub(crate) struct Reader<'a>(pub(crate) &'a [u8]);

impl<'a> Reader<'a> {
    pub(crate) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, tail) = self.0.split_at_checked(n)?;
        self.0 = tail;
        Some(head)
    }
    pub(crate) fn u32(&mut self) -> Option<u32> {
        self.take(4)?.try_into().ok().map(u32::from_le_bytes)
    }
    pub(crate) fn f64(&mut self) -> Option<f64> {
        self.take(8)?.try_into().ok().map(f64::from_le_bytes)
    }
    pub(crate) fn f64s(&mut self, n: usize) -> Option<Vec<f64>> {
        let raw = self.take(n.checked_mul(8)?)?;
        Some(
            raw.chunks_exact(8).map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])).collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_reconstructor_loads_back_equal_and_keys_differ_by_input() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        let params = ReconstructorParams { raster: [16, 16], ..ReconstructorParams::default() };
        let folder = tempfile::Builder::new().prefix("eitskin-cache-").tempdir().unwrap();
        let dir = folder.path().join("cache"); // made by the first save, as a user's cache folder is
        let (built, hit) = load_or_build(&dir, &spec, &params).unwrap();
        assert!(!hit);
        let (loaded, hit) = load_or_build(&dir, &spec, &params).unwrap();
        assert!(hit, "the second start must come from the cache");
        assert_eq!(loaded, built);

        let other = ReconstructorParams { hyperparameter: 0.05, ..params };
        assert_ne!(cache_key(&spec, &params).unwrap(), cache_key(&spec, &other).unwrap());
        spec.electrodes.contact_impedance *= 2.0;
        assert_ne!(cache_key(&spec, &params).unwrap(), cache_key(&SensorSpec::square_hydrogel(), &params).unwrap());

        let key = cache_key(
            &SensorSpec {
                mesh: eitskin::MeshParams { triangles: 400, ..Default::default() },
                ..SensorSpec::square_hydrogel()
            },
            &params,
        )
        .unwrap();
        let bytes = encode_reconstructor(&built, &key);
        assert!(decode_reconstructor(&bytes[..bytes.len() - 1], &key).is_none(), "a torn file is not loaded");
        assert!(decode_reconstructor(&bytes, &[0; 32]).is_none(), "another key is not loaded");
    }
}
