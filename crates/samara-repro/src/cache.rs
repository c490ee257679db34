//! Stage cache: a finished stage stores its result (JSON) with a key computed from
//! everything it depends on (its options, the samara version, the keys of the stages it
//! reads). A re-run whose key matches and whose output files exist reuses the result.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// One stored stage: its key, the files it wrote (relative to the output directory) and
/// its result (the stage's typed result as JSON; see [`crate::results`]).
#[derive(Serialize, Deserialize)]
struct Entry {
    files: Vec<String>,
    key: String,
    result: Value,
}

/// FNV-1a 64-bit hash (stable across runs and platforms, unlike `DefaultHasher`).
pub fn fnv1a(parts: &[&str]) -> String {
    let mut h: u64 = 0xcbf29ce484222325;
    for p in parts {
        for b in p.as_bytes().iter().chain(std::iter::once(&0xffu8)) {
            h ^= *b as u64;
            h = h.wrapping_mul(0x100000001b3);
        }
    }
    format!("{h:016x}")
}

/// The cache directory of a run.
pub struct Cache {
    dir: PathBuf,
    fresh: bool,
}

impl Cache {
    /// Cache under `out/.cache`; `fresh` ignores stored entries (they are overwritten).
    pub fn new(out: &Path, fresh: bool) -> Self {
        Cache {
            dir: out.join(".cache"),
            fresh,
        }
    }

    /// The stored result of `stage` if its key matches and every listed file exists.
    pub fn get(&self, stage: &str, key: &str, out: &Path) -> Option<Value> {
        if self.fresh {
            return None;
        }
        let text = std::fs::read_to_string(self.dir.join(format!("{stage}.json"))).ok()?;
        let e: Entry = serde_json::from_str(&text).ok()?;
        if e.key != key || e.files.iter().any(|p| !out.join(p).exists()) {
            return None;
        }
        Some(e.result)
    }

    /// Store a finished stage (atomically).
    pub fn put(
        &self,
        stage: &str,
        key: &str,
        files: &[String],
        result: &Value,
    ) -> std::io::Result<()> {
        std::fs::create_dir_all(&self.dir)?;
        let e = Entry {
            files: files.to_vec(),
            key: key.to_string(),
            result: result.clone(),
        };
        let text = serde_json::to_string(&e).map_err(std::io::Error::other)?;
        samara_report::write_atomic(&self.dir.join(format!("{stage}.json")), text.as_bytes())
            .map_err(|e| std::io::Error::other(e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_is_stable_and_separates_parts() {
        assert_eq!(fnv1a(&["a"]), fnv1a(&["a"]));
        assert_ne!(fnv1a(&["ab", "c"]), fnv1a(&["a", "bc"]));
        // Known FNV-1a 64 value of the empty input followed by the 0xff separator.
        let mut h: u64 = 0xcbf29ce484222325;
        h ^= 0xff;
        h = h.wrapping_mul(0x100000001b3);
        assert_eq!(fnv1a(&[""]), format!("{h:016x}"));
    }

    #[test]
    fn cache_round_trip_and_invalidation() {
        let dir = std::env::temp_dir().join(format!("samara-cache-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("f.txt"), "x").unwrap();
        let c = Cache::new(&dir, false);
        let r = serde_json::json!({"v": 1});
        c.put("s", "k1", &["f.txt".into()], &r).unwrap();
        assert_eq!(c.get("s", "k1", &dir), Some(r.clone()));
        assert_eq!(c.get("s", "k2", &dir), None);
        std::fs::remove_file(dir.join("f.txt")).unwrap();
        assert_eq!(c.get("s", "k1", &dir), None);
        assert_eq!(Cache::new(&dir, true).get("s", "k1", &dir), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
