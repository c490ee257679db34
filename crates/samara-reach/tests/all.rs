//! Every integration test file of samara-reach in one test binary: one link and one copy
//! of the monomorphised library code instead of one per file (most of the CI build
//! time went to those). Each file is a module: `cargo test -p samara-reach --test all
//! FILE::` runs one. `every_test_file_is_built` fails for a file left out.

mod adaptive;
mod common;
mod containment;
mod differential_plants;
mod discrete;
mod network_step;
mod plant_semantics;
mod system_containment;
mod tmflow;

/// See [`samara_testkit::assert_every_test_file_is_built`].
#[test]
fn every_test_file_is_built() {
    samara_testkit::assert_every_test_file_is_built(env!("CARGO_MANIFEST_DIR"), &[]);
}
