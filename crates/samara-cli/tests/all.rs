//! Every integration test file of samara-cli in one test binary: one link and one copy
//! of the monomorphised library code instead of one per file (most of the CI build
//! time went to those). Each file is a module: `cargo test -p samara-cli --test all
//! FILE::` runs one. `every_test_file_is_built` fails for a file left out.

mod broken_pipe;
mod cliio_fuzz_flags;
mod cliio_regressions;
mod conv_time_limits;
mod degenerate_vnnlib;
mod plant_cli;
mod reach_adaptive_shards;
mod reach_cli;
mod reach_discrete_cli;
mod reach_lost_enclosure;
mod reproduce_cli;
mod shard_integrity;
mod shard_merge;
mod simulate_cli;
mod support;
mod system_cli;
mod thin_region_vnnlib;
mod threads_cli;
mod time_limits;
mod train_cli;
mod train_closed_loop;
mod units_check_cli;
mod verdict_regressions;
mod verify_cli;
mod vnncomp_cli;

/// See [`samara_testkit::assert_every_test_file_is_built`].
#[test]
fn every_test_file_is_built() {
    samara_testkit::assert_every_test_file_is_built(env!("CARGO_MANIFEST_DIR"), &[]);
}
