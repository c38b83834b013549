//! Square binary fiducial markers: dictionary, rendering, and a fast allocation-free detector
//! with cross-ratio cell sampling.
#![deny(missing_docs)]

pub mod cross_ratio;
pub mod decode;
pub mod dictionary;
pub mod error;
pub mod family;
pub mod image;
pub mod render;

pub use crate::cross_ratio::CrossRatioFrame;
pub use crate::decode::{CellReading, DecodeParams, Decoded, Rejection, decode, read_cells};
pub use crate::dictionary::{Dictionary, GenerateParams, Match, hamming};
pub use crate::error::FiducialError;
pub use crate::family::MarkerFamily;
pub use crate::image::{Corners, GrayView, ImageError};
pub use crate::render::{RenderOptions, RenderedMarker, render_marker, render_svg};
