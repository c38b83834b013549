//! Square binary fiducial markers: dictionary, rendering, and a fast allocation-free detector
//! with cross-ratio cell sampling.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]

pub mod contour;
pub mod detector;
pub mod image;
pub mod quad;
pub mod refine;
pub mod synth;
pub mod threshold;

pub use crate::detector::{Detector, DetectorConfig, Quad};
pub use crate::image::{Corners, GrayView, ImageError};
pub use crate::threshold::{Threshold, rgb_to_gray, rgba_to_gray};
