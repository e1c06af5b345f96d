//! The reconstructor cache: the forward model's [`Linearisation`] (Jacobian and its factors,
//! background measurements, mesh) saved to a file named by a hash of everything it depends on (spec,
//! protocol, mesh settings and this crate's version), so a second start loads it instead of
//! solving the forward model again. The reconstructor itself (prior, λ, normalisation,
//! channels, raster) is derived from it in milliseconds to seconds (thousands of channels), so
//! one file serves them all. The automatic λ, an eigendecomposition of the channels' system
//! away (seconds at thousands of channels), is kept beside it ([`cached_hyperparameter`]):
//! `EITSKINL`, the 32-byte key (which also hashes the prior, normalisation, channel mask and
//! every noise variance) and λ (f64).
//!
//! File layout (little-endian): `EITSKINR`, format version (u32), the 32-byte key, node,
//! triangle, electrode and measurement counts (u32), the nodes (2 × f64 each), the triangles
//! (3 × u32 each), per electrode its node count and nodes (u32), the background
//! measurements (f64), then the Jacobian (measurements × triangles f64, column-major) and its
//! factors P·B ([`eitskin::forward::JacobianFactors`]; P measurements × L(L−1)/2 pairs, B
//! pairs × triangles, f64, column-major). A file that does not match is rebuilt.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, Weak};

use eitskin::inverse::{Channels, Linearisation};
use eitskin::{Mesh, Reconstructor, ReconstructorParams, SensorSpec};
use sha2::{Digest, Sha256};

use crate::Error;

const MAGIC: &[u8; 8] = b"EITSKINR";
const FORMAT: u32 = 3;

/// The cache key: SHA-256 of the spec, its protocol patterns and mesh settings (the
/// reconstructor's parameters are not in it: they are derived after loading).
pub fn cache_key(spec: &SensorSpec) -> Result<[u8; 32], Error> {
    key_of(spec, "linearisation")
}

/// SHA-256 of this crate's version, the spec, its protocol patterns, its mesh settings and `extra`.
pub(crate) fn key_of(spec: &SensorSpec, extra: &str) -> Result<[u8; 32], Error> {
    let mut hash = Sha256::new();
    hash.update(env!("CARGO_PKG_VERSION"));
    // The mask only selects channels of the linearisation, and the mount places the sensor on a
    // robot: one cache file serves every mask and mount.
    let unmasked = SensorSpec { mask: eitskin::ChannelMask::default(), mount: None, ..spec.clone() };
    hash.update(crate::spec_to_toml(&unmasked));
    // Custom protocols are not in the TOML: hash the patterns themselves.
    hash.update(format!("{:?}", spec.protocol()?));
    hash.update(format!("{:?} {extra}", spec.mesh));
    Ok(hash.finalize().into())
}

/// The file the linearisation for `spec` is cached in, under `dir`.
pub fn cache_path(dir: &Path, spec: &SensorSpec) -> Result<PathBuf, Error> {
    Ok(cache_file(dir, "linearisation", &cache_key(spec)?))
}

/// The reconstructor for `spec` and `params` (every channel used), its linearisation the one
/// this process holds for `spec` ([`shared_linearisation`]), else loaded from `dir` if there,
/// else computed and saved (best effort); the flag says whether it was held or cached.
pub fn load_or_build(
    dir: &Path,
    spec: &SensorSpec,
    params: &ReconstructorParams,
) -> Result<(Reconstructor, bool), Error> {
    let (linearisation, hit) = shared_linearisation(dir, spec)?;
    let channels = Channels::all(linearisation.measurements());
    Ok((Reconstructor::from_linearisation(linearisation, params, channels)?, hit))
}

/// [`load_linearisation`], shared with every other user of the same spec's in this process
/// while any holds it: a fleet of identical patches (`eitskin serve`) keeps one Jacobian (8 MB
/// on the paper's sheet) and the products its derivations keep with it, not one a sensor.
/// The flag says whether it came from the cache or this process.
pub fn shared_linearisation(dir: &Path, spec: &SensorSpec) -> Result<(Arc<Linearisation>, bool), Error> {
    /// The linearisations handed out, by key; those no longer held are dropped as others come.
    static HELD: Mutex<Vec<([u8; 32], Weak<Linearisation>)>> = Mutex::new(Vec::new());
    let key = cache_key(spec)?;
    let held = || HELD.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(linearisation) = held().iter().find(|(k, _)| *k == key).and_then(|(_, held)| held.upgrade()) {
        return Ok((linearisation, true));
    }
    // Loaded without the lock held: sensors of other specs load meanwhile (and one of the same
    // spec loading meanwhile is kept, this one dropped).
    let (loaded, hit) = load_linearisation(dir, spec)?;
    let mut held = held();
    if let Some(linearisation) = held.iter().find(|(k, _)| *k == key).and_then(|(_, held)| held.upgrade()) {
        return Ok((linearisation, true));
    }
    let linearisation = Arc::new(loaded);
    held.retain(|(k, held)| *k != key && held.strong_count() > 0);
    held.push((key, Arc::downgrade(&linearisation)));
    Ok((linearisation, hit))
}

/// The linearisation of `spec`, loaded from `dir` if there, else computed and saved (best
/// effort); the flag says whether it came from the cache.
pub fn load_linearisation(dir: &Path, spec: &SensorSpec) -> Result<(Linearisation, bool), Error> {
    let key = cache_key(spec)?;
    let build = || Ok(Linearisation::new(&spec.forward_model()?, spec.conductivity)?);
    cached(&cache_file(dir, "linearisation", &key), &key, decode_linearisation, build, encode_linearisation)
}

/// The automatic λ of `spec` for a prior, normalisation and noise-weighted `channels`, loaded
/// from `dir` if chosen before for exactly these (the channels' mask and every variance), else
/// `choose`n and saved (best effort); the flag says whether it came from the cache.
pub fn cached_hyperparameter(
    dir: &Path,
    spec: &SensorSpec,
    params: &ReconstructorParams,
    channels: &Channels,
    choose: impl FnOnce() -> Result<f64, Error>,
) -> Result<(f64, bool), Error> {
    let said = format!("auto-hyperparameter {:?} {} {channels:?}", params.prior, params.normalised);
    let key = key_of(spec, &said)?;
    let decode = |bytes: &[u8], key: &[u8; 32]| {
        let rest = bytes.strip_prefix(MAGIC_LAMBDA)?.strip_prefix(key.as_slice())?;
        Some(f64::from_le_bytes(rest.try_into().ok()?)).filter(|l| l.is_finite() && *l > 0.0)
    };
    let encode = |lambda: &f64, key: &[u8; 32]| [MAGIC_LAMBDA, key.as_slice(), &lambda.to_le_bytes()].concat();
    cached(&cache_file(dir, "hyperparameter", &key), &key, decode, choose, encode)
}

/// The first bytes of a cached λ's file.
const MAGIC_LAMBDA: &[u8] = b"EITSKINL";

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
pub fn encode_linearisation(lin: &Linearisation, key: &[u8; 32]) -> Vec<u8> {
    let mesh = lin.mesh();
    let jacobian = lin.jacobian();
    let mut out = Vec::with_capacity(64 + 8 * (jacobian.nrows() * jacobian.ncols() + 2 * mesh.nodes().len()));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT.to_le_bytes());
    out.extend_from_slice(key);
    let counts = [mesh.nodes().len(), mesh.triangles().len(), mesh.electrodes().len(), lin.measurements()];
    for n in counts {
        out.extend_from_slice(&(n as u32).to_le_bytes());
    }
    for x in mesh.nodes().iter().flatten() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    for n in mesh.triangles().iter().flatten() {
        out.extend_from_slice(&(*n as u32).to_le_bytes());
    }
    for electrode in mesh.electrodes() {
        out.extend_from_slice(&(electrode.len() as u32).to_le_bytes());
        for n in electrode {
            out.extend_from_slice(&(*n as u32).to_le_bytes());
        }
    }
    for v in lin.background() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let factors = lin.factors();
    for matrix in [jacobian, factors.patterns.as_ref(), factors.basis.as_ref()] {
        for k in 0..matrix.ncols() {
            for x in matrix.col(k).iter() {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    out
}

/// A linearisation from cache bytes, or `None` if they are not a complete file for `key`.
pub fn decode_linearisation(bytes: &[u8], key: &[u8; 32]) -> Option<Linearisation> {
    let mut r = Reader(bytes);
    if r.take(8)? != MAGIC || r.u32()? != FORMAT || r.take(32)? != key {
        return None;
    }
    let [nodes, triangles, electrodes, measurements] = [r.u32()?, r.u32()?, r.u32()?, r.u32()?].map(|n| n as usize);
    let coordinates = r.f64s(nodes.checked_mul(2)?)?;
    let nodes: Vec<[f64; 2]> = coordinates.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    let mut corners = Vec::with_capacity(triangles.min(1 << 24));
    for _ in 0..triangles {
        corners.push([r.u32()? as usize, r.u32()? as usize, r.u32()? as usize]);
    }
    let mut sets = Vec::with_capacity(electrodes.min(1 << 16));
    for _ in 0..electrodes {
        let count = r.u32()? as usize;
        sets.push((0..count).map(|_| r.u32().map(|n| n as usize)).collect::<Option<Vec<_>>>()?);
    }
    let background = r.f64s(measurements)?;
    let values = r.f64s(measurements.checked_mul(triangles)?)?;
    let pairs = eitskin::forward::JacobianFactors::pairs(electrodes);
    let patterns = r.f64s(measurements.checked_mul(pairs)?)?;
    let basis = r.f64s(pairs.checked_mul(triangles)?)?;
    if !r.0.is_empty() {
        return None;
    }
    let mesh = Mesh::new(nodes, corners, sets).ok()?;
    Linearisation::from_parts(&values, [&patterns, &basis], background, mesh)
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
    fn a_chosen_lambda_is_kept_for_exactly_its_channels_and_noise() {
        let spec = SensorSpec::square_hydrogel();
        let params = ReconstructorParams::default();
        let folder = tempfile::Builder::new().prefix("eitskin-cache-").tempdir().unwrap();
        let dir = folder.path().join("cache");
        let channels = Channels::all(120).with_variance(vec![1e-6; 120]);
        let calls = std::cell::Cell::new(0);
        let chosen = &calls;
        let choose = |lambda: f64| {
            move || {
                chosen.set(chosen.get() + 1);
                Ok(lambda)
            }
        };
        assert_eq!(cached_hyperparameter(&dir, &spec, &params, &channels, choose(0.25)).unwrap(), (0.25, false));
        assert_eq!(cached_hyperparameter(&dir, &spec, &params, &channels, choose(9.0)).unwrap(), (0.25, true));
        // Another noise, mask or normalisation is another λ.
        let noisier = Channels::all(120).with_variance(vec![2e-6; 120]);
        let masked = channels.clone().masked(&[false]);
        let normalised = ReconstructorParams { normalised: true, ..params };
        assert_eq!(cached_hyperparameter(&dir, &spec, &params, &noisier, choose(0.5)).unwrap(), (0.5, false));
        assert_eq!(cached_hyperparameter(&dir, &spec, &params, &masked, choose(0.75)).unwrap(), (0.75, false));
        assert_eq!(cached_hyperparameter(&dir, &spec, &normalised, &channels, choose(1.5)).unwrap(), (1.5, false));
        // A torn file is chosen again.
        let said = format!("auto-hyperparameter {:?} {} {channels:?}", params.prior, params.normalised);
        let path = cache_file(&dir, "hyperparameter", &key_of(&spec, &said).unwrap());
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert_eq!(cached_hyperparameter(&dir, &spec, &params, &channels, choose(0.3)).unwrap(), (0.3, false));
        assert_eq!(calls.get(), 5, "chosen each time but the second");
    }

    #[test]
    fn a_saved_linearisation_loads_back_equal_and_keys_differ_by_input() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        // (No other test of this process holds this sheet's linearisation.)
        spec.conductivity = 1.0625;
        let params = ReconstructorParams { raster: [16, 16], ..ReconstructorParams::default() };
        let folder = tempfile::Builder::new().prefix("eitskin-cache-").tempdir().unwrap();
        let dir = folder.path().join("cache"); // made by the first save, as a user's cache folder is
        let (built, hit) = load_or_build(&dir, &spec, &params).unwrap();
        assert!(!hit);
        let (from_file, hit) = load_linearisation(&dir, &spec).unwrap();
        assert!(hit, "the second start must come from the cache");
        assert_eq!(&from_file, built.linearisation().as_ref());
        let other = ReconstructorParams { hyperparameter: 0.05, ..params };
        let (loaded, hit) = load_or_build(&dir, &spec, &other).unwrap();
        assert!(hit && Arc::ptr_eq(loaded.linearisation(), built.linearisation()), "shared, whatever λ it asks for");
        assert_eq!(loaded.derive(0.1, loaded.channels().clone()).unwrap(), built);

        let masked =
            SensorSpec { mask: eitskin::ChannelMask { channels: vec![3], electrodes: vec![] }, ..spec.clone() };
        assert_eq!(cache_key(&masked).unwrap(), cache_key(&spec).unwrap(), "a mask needs no other linearisation");
        spec.electrodes.contact_impedance *= 2.0;
        assert_ne!(cache_key(&spec).unwrap(), cache_key(&SensorSpec::square_hydrogel()).unwrap());

        let key = cache_key(&SensorSpec {
            mesh: eitskin::MeshParams { triangles: 400, ..Default::default() },
            ..SensorSpec::square_hydrogel()
        })
        .unwrap();
        let bytes = encode_linearisation(built.linearisation(), &key);
        assert_eq!(decode_linearisation(&bytes, &key).as_ref(), Some(built.linearisation().as_ref()));
        assert!(decode_linearisation(&bytes[..bytes.len() - 1], &key).is_none(), "a torn file is not loaded");
        assert!(decode_linearisation(&bytes, &[0; 32]).is_none(), "another key is not loaded");
    }

    /// A spec's linearisation is one in the process while held (whichever cache folder asked),
    /// another spec's its own; once none holds it, it is loaded again, from the file.
    #[test]
    fn a_linearisation_is_shared_while_held() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        spec.conductivity = 0.8125; // no other test of this process holds this sheet's
        let folder = tempfile::Builder::new().prefix("eitskin-cache-").tempdir().unwrap();
        let (dir, elsewhere) = (folder.path().join("cache"), folder.path().join("other"));
        let (first, hit) = shared_linearisation(&dir, &spec).unwrap();
        assert!(!hit);
        let (second, hit) = shared_linearisation(&elsewhere, &spec).unwrap();
        assert!(hit && Arc::ptr_eq(&first, &second));
        let mut thicker = spec.clone();
        thicker.conductivity *= 2.0;
        let (other_sheet, _) = shared_linearisation(&dir, &thicker).unwrap();
        assert!(!Arc::ptr_eq(&other_sheet, &first));
        let bytes = encode_linearisation(&first, &cache_key(&spec).unwrap());
        let weak = Arc::downgrade(&first);
        drop((first, second));
        assert!(weak.upgrade().is_none());
        let (again, hit) = shared_linearisation(&dir, &spec).unwrap();
        assert!(hit, "from the file");
        assert_eq!(encode_linearisation(&again, &cache_key(&spec).unwrap()), bytes);
    }
}
