//! The memory this process may still take: the system's available memory, lowered to the
//! room left under the control group's limit where one is set (containers, CI runners); and the
//! last-level cache the processor's cores share.

use std::path::Path;

/// Bytes of memory available to this process now, or `None` where the system does not say
/// (not Linux, or `/proc` not mounted).
pub fn available_memory() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let system = mem_available(&meminfo)?;
    Some(match cgroup_room(Path::new("/sys/fs/cgroup")) {
        Some(room) => system.min(room),
        None => system,
    })
}

/// The most memory this process has had resident so far (`VmHWM`), in bytes, or `None` where
/// the system does not say.
pub fn peak_memory() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    kib_field(&status, "VmHWM:")
}

/// Bytes of the largest data cache of the first processor (its last level, which the cores
/// share), or `None` where the system does not say (not Linux, or `/sys` not mounted).
///
/// Read from sysfs rather than by `cpuid`: the same files on every architecture Linux runs on.
pub fn last_level_cache() -> Option<f64> {
    cache_bytes(Path::new("/sys/devices/system/cpu/cpu0/cache"))
}

/// The largest data or unified cache under a sysfs `cache` folder (its `index*/size` and
/// `index*/type`), in bytes.
fn cache_bytes(folder: &Path) -> Option<f64> {
    let read = |index: &Path, name: &str| std::fs::read_to_string(index.join(name)).ok();
    std::fs::read_dir(folder)
        .ok()?
        .filter_map(|entry| {
            let index = entry.ok()?.path();
            let kind = read(&index, "type")?;
            if kind.trim() == "Instruction" {
                return None;
            }
            size_bytes(read(&index, "size")?.trim())
        })
        .reduce(f64::max)
}

/// A sysfs cache size (`32768K`, `8M`, `512`) in bytes.
fn size_bytes(size: &str) -> Option<f64> {
    let (number, scale) = match size.as_bytes().last()? {
        b'K' => (&size[..size.len() - 1], 1024.0),
        b'M' => (&size[..size.len() - 1], 1024.0 * 1024.0),
        b'G' => (&size[..size.len() - 1], 1024.0 * 1024.0 * 1024.0),
        _ => (size, 1.0),
    };
    let number: f64 = number.parse().ok()?;
    (number.is_finite() && number > 0.0).then_some(number * scale)
}

/// A `kB` field of a `/proc` text, in bytes.
fn kib_field(text: &str, name: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// `MemAvailable` of a `/proc/meminfo` text, in bytes.
fn mem_available(meminfo: &str) -> Option<f64> {
    kib_field(meminfo, "MemAvailable:")
}

/// The room under a cgroup v2 limit (`memory.max` less `memory.current`), in bytes; `None`
/// where no limit is set.
fn cgroup_room(root: &Path) -> Option<f64> {
    let read = |name: &str| std::fs::read_to_string(root.join(name)).ok()?.trim().parse::<f64>().ok();
    let (max, current) = (read("memory.max")?, read("memory.current")?);
    Some((max - current).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_and_cgroup_limits_are_read_in_bytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:         1000 kB\nMemAvailable:   2000000 kB\n";
        assert_eq!(mem_available(text), Some(2_048_000_000.0));
        assert_eq!(mem_available("MemTotal: 5 kB\n"), None);
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(cgroup_room(dir.path()), None);
        std::fs::write(dir.path().join("memory.max"), "max\n").unwrap();
        std::fs::write(dir.path().join("memory.current"), "1000\n").unwrap();
        assert_eq!(cgroup_room(dir.path()), None, "\"max\" is no limit");
        std::fs::write(dir.path().join("memory.max"), "5000\n").unwrap();
        assert_eq!(cgroup_room(dir.path()), Some(4000.0));
        assert!(available_memory().is_none_or(|b| b > 0.0));
        assert!(peak_memory().is_none_or(|b| b > 0.0));
    }

    #[test]
    fn the_largest_data_cache_is_the_last_level() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(cache_bytes(&dir.path().join("none")), None);
        assert_eq!(cache_bytes(dir.path()), None, "no cache listed");
        for (index, kind, size) in [
            ("index0", "Data", "32K"),
            ("index1", "Instruction", "64M"),
            ("index2", "Unified", "1024K"),
            ("index3", "Unified", "32768K"),
        ] {
            let folder = dir.path().join(index);
            std::fs::create_dir(&folder).unwrap();
            std::fs::write(folder.join("type"), format!("{kind}\n")).unwrap();
            std::fs::write(folder.join("size"), format!("{size}\n")).unwrap();
        }
        assert_eq!(cache_bytes(dir.path()), Some(32.0 * 1024.0 * 1024.0));
        assert_eq!(size_bytes("8M"), Some(8.0 * 1024.0 * 1024.0));
        assert_eq!(size_bytes("512"), Some(512.0));
        for bad in ["", "K", "-1K", "0K", "NaNK", "12Q"] {
            assert_eq!(size_bytes(bad), None, "{bad:?}");
        }
        assert!(last_level_cache().is_none_or(|b| b >= 1024.0));
    }
}
