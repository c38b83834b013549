//! Vision-based tracking of mobile robots in formation: rig model, measurement transform, tracker and CLI.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]
