//! The published reference files, for the tests of every crate (included by path; the
//! body is samara-testkit's, so there is one helper and one message).
#![allow(dead_code)] // each test file uses its own subset

include!("../../../samara-testkit/src/reference.rs");
