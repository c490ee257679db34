//! Every integration test file of samara-bounds in one test binary: one link and one copy
//! of the monomorphised library code instead of one per file (most of the CI build
//! time went to those). Each file is a module: `cargo test -p samara-bounds --test all
//! FILE::` runs one. `every_test_file_is_built` fails for a file left out.

mod linset;
mod one_input;
mod rounding;
mod smooth_fold;
mod soundness;
mod sparse_storage;
mod support;

/// See [`samara_testkit::assert_every_test_file_is_built`].
#[test]
fn every_test_file_is_built() {
    samara_testkit::assert_every_test_file_is_built(env!("CARGO_MANIFEST_DIR"), &[]);
}
