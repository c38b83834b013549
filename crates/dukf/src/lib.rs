//! A generic (dual) unscented Kalman filter over nalgebra static dimensions; knows nothing about robots.
//!
//! (Crate under construction: see `docs/architecture.md`.)
#![deny(missing_docs)]
