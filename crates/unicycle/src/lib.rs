//! Unicycle robots and the polar leader-follower formation model with a camera offset.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]
