//! One module per subcommand. Each exposes an `Args` struct (clap) and a `run` function.

/// Any error a subcommand reports; printed as one line by `main`.
pub type CliError = Box<dyn std::error::Error + Send + Sync + 'static>;

pub mod demo;
pub mod detect;
pub mod detect_robots;
pub mod info;
pub mod markers;
pub mod render;
pub mod reproduce;
pub mod reproduce_scenes;
pub mod track;
