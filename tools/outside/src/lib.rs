//! Nothing but the test in `tests/outside.rs`: the public crates used from outside the
//! workspace (see README.md).
