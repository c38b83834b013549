//! A pure-Rust synthetic camera: ray-cast scenes of unicycle robots carrying marker rigs, with exact ground truth.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]
