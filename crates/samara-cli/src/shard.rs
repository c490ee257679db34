//! `--shard I/N`: the sweeping commands compute only their share and write it as a shard
//! file (`samara merge`, in `merge.rs`, puts them back together). The shard files, their
//! digests and checks are `samara_app::shard`'s.

pub use samara_app::shard::{digest_inputs, write, Shard};
