//! Re-sealing an edited shard file as a forger would: its payload digest recomputed, so
//! only the merge's deeper checks can catch the edit.
#![allow(dead_code)] // each test file uses its own subset

use serde_json::Value;
use std::path::Path;

/// 64-bit FNV-1a (its published offset basis and prime), written here independently of
/// samara's digest.
pub fn fnv1a(b: &[u8]) -> String {
    let mut h: u64 = 14_695_981_039_346_656_037;
    for x in b {
        h ^= u64::from(*x);
        h = h.wrapping_mul(1_099_511_628_211);
    }
    format!("{h:016x}")
}

/// Write the shard document `v` to `p`; with `reseal`, with its `digest` recomputed (the
/// FNV-1a of the canonical serde_json text of the document without `digest`).
pub fn write_shard(p: &Path, mut v: Value, reseal: bool) {
    if reseal {
        v.as_object_mut().unwrap().remove("digest");
        let d = fnv1a(serde_json::to_string(&v).unwrap().as_bytes());
        v["digest"] = Value::String(d);
    }
    std::fs::write(p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}
