//! Pinhole and OpenGL camera models, lens distortion, exponential map, POSIT and Levenberg-Marquardt pose solvers.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]
