//! Every environment variable bettimill reads, in one place ([`EnvVars`]), and the only
//! functions that read them ([`var`], [`seconds`], [`number`]).
//!
//! A leaf crate without dependencies, so that every crate that reads the environment (the
//! executor, the CLI, the test helpers) can depend on it. `tests/tidy.rs` checks that
//! `std::env::var` appears in no other source file; docs/environment.md is the users' list
//! (the test hooks and the test suite's variables are left out of it).

mod env;

pub use env::{number, seconds, var, EnvVars};
