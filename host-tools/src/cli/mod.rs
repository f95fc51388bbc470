//! Command-line front ends, one module per subcommand. Each module owns its `Args` (clap) and a
//! `run` function; `main.rs` only dispatches.

pub mod additive;
pub mod compile;
pub mod cure_check;
pub mod grow;
pub mod preview;
pub mod send;
pub mod stats;
pub mod timebased;
