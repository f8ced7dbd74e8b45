//! Every environment variable bettimill reads, in one place ([`EnvVars`]), and the only
//! functions that read them ([`var`], [`seconds`], [`number`], [`names_starting_with`]).
//!
//! A leaf crate without dependencies, so that every crate that reads the environment (the
//! executor, the CLI, the test helpers and tests) can depend on it. `tests/tidy.rs` checks
//! that `std::env::var` appears in no other Rust file, and that every variable a ci/ script
//! or a Python file reads is listed here; docs/environment.md is the users' list (the test
//! hooks and the variables of the tests and scripts are left out of it).

mod env;

pub use env::{names_starting_with, number, seconds, var, EnvVars};
