//! formation-tracker: the thin composition of `fiducial`, `pose`, `unicycle` and `dukf`.
#![deny(missing_docs)]

pub mod mount;
pub mod scenario;
