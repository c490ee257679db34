//! Every integration test file of samara-nn in one test binary: one link and one copy
//! of the monomorphised library code instead of one per file (most of the CI build
//! time went to those). Each file is a module: `cargo test -p samara-nn --test all
//! FILE::` runs one. `every_test_file_is_built` fails for a file left out.

mod fuzz;
mod graph_import;
mod import_memory;
mod nan;
mod nnet;
mod onnx_legacy_conv;
mod onnx_reference;
mod onnx_roundtrip;
mod sparse_layers;
mod vnncomp_networks;

/// See [`samara_testkit::assert_every_test_file_is_built`].
#[test]
fn every_test_file_is_built() {
    samara_testkit::assert_every_test_file_is_built(
        env!("CARGO_MANIFEST_DIR"),
        &["import_memory_env.rs"],
    );
}
