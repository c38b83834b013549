//! Square binary fiducial markers: dictionary, rendering, and a fast allocation-free detector
//! with cross-ratio cell sampling.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]

pub mod image;

pub use crate::image::{Corners, GrayView, ImageError};
