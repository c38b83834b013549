//! The follower's own inputs per frame, from a CSV file.
//!
//! The tracker needs the follower's inputs `(v2, w2)` (they drive the polar model, spec 2.4)
//! and the camera pan (it enters the measurement transform, spec 2.5). The camera does not
//! see them; the caller supplies them, for the CLI as a CSV file:
//!
//! ```text
//! # comment lines start with '#'
//! frame,v2,w2,pan
//! 0,0.0,0.0,0.0
//! 1,0.35,0.02,0.0
//! ```
//!
//! - A header line names the columns, in any order: exactly one key column, `frame` (frame
//!   number from 0, integer) or `t` (seconds); `v2` (m/s) and `w2` (rad/s); optionally
//!   `pan` (rad, left positive). Other columns are ignored. Keys must increase strictly.
//! - A row gives the inputs the follower applied over the interval that **ends** at that
//!   frame (since the previous frame), and the pan at that frame.
//! - Between rows the last row holds (zero-order hold): the frame uses the row with the
//!   largest key `<=` its own (for `t`, within 1 microsecond). Before the first row there is
//!   no value ([`FollowerInputs::at`] returns `None`) and the caller falls back to zero
//!   inputs and the configured pan.
//!
//! Without a file the CLI assumes the follower stands still (`v2 = w2 = 0`) with the
//! configured pan, and says so on stderr.

use std::path::{Path, PathBuf};

use unicycle::Inputs;

/// The largest follower speed accepted from odometry, m/s (`v2`, the inputs CSV and bag
/// `Odometry`/`Twist`): a ground robot carrying a camera for this does not drive faster;
/// `v = 1e300` reset the track every other frame.
pub const MAX_SPEED: f64 = 20.0;

/// The largest follower turn rate accepted from odometry, rad/s (`w2`).
pub const MAX_TURN_RATE: f64 = 20.0;

/// Errors reading a follower-inputs CSV. Line numbers count from 1.
#[derive(Debug, thiserror::Error)]
pub enum InputsError {
    /// The file could not be read.
    #[error("cannot read follower inputs {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// What [`FollowerInputs::parse`] refused, in the named file.
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong in it.
        source: Box<InputsError>,
    },
    /// A required column is missing from the header (or both `frame` and `t` are present).
    #[error("follower inputs: header must have {what}")]
    Header {
        /// What is missing or wrong.
        what: &'static str,
    },
    /// A value is not a number, or not finite.
    #[error("follower inputs line {line}, column {column}: {value:?} is not a finite number")]
    BadValue {
        /// Line number.
        line: usize,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// A value is a number but physically impossible for the follower.
    #[error("follower inputs line {line}, column {column}: {value:?} is outside {range}")]
    OutOfRange {
        /// Line number.
        line: usize,
        /// Column name.
        column: String,
        /// The value.
        value: f64,
        /// The range allowed, with its unit.
        range: &'static str,
    },
    /// A column name appears twice in the header.
    #[error("follower inputs: column `{column}` appears twice in the header")]
    DuplicateColumn {
        /// The name.
        column: String,
    },
    /// The frame key is not a whole number of frames.
    #[error(
        "follower inputs line {line}, column frame: {value:?} is not a frame number (a whole number >= 0)"
    )]
    BadFrame {
        /// 1-based line number.
        line: usize,
        /// The field as written.
        value: String,
    },
    /// A row has fewer or more fields than the header.
    #[error(
        "follower inputs line {line}: {found} fields, the header has {expected} (every row has one field per column)"
    )]
    ShortRow {
        /// Line number.
        line: usize,
        /// Fields found.
        found: usize,
        /// Fields expected.
        expected: usize,
    },
    /// Keys do not increase strictly.
    #[error("follower inputs line {line}: {key} = {value} does not increase")]
    NotIncreasing {
        /// Line number.
        line: usize,
        /// `frame` or `t`.
        key: &'static str,
        /// The value.
        value: f64,
    },
    /// No data rows.
    #[error("follower inputs: no data rows")]
    Empty,
}

/// Which column keys the rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    /// Frame number.
    Frame,
    /// Time, seconds.
    Time,
}

/// One frame's follower inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputSample {
    /// `(v2, w2)` over the interval ending at the frame.
    pub inputs: Inputs,
    /// Camera pan at the frame, if the file has a `pan` column.
    pub pan: Option<f64>,
}

/// The parsed CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowerInputs {
    key: Key,
    rows: Vec<(f64, InputSample)>,
}

impl FollowerInputs {
    /// Reads and parses a file.
    ///
    /// # Errors
    /// Any [`InputsError`].
    pub fn from_path(path: &Path) -> Result<Self, InputsError> {
        let bytes = crate::textfile::read_bounded(path, crate::textfile::MAX_TEXT_BYTES).map_err(
            |source| InputsError::Io {
                path: path.to_path_buf(),
                source,
            },
        )?;
        let text = String::from_utf8(bytes).map_err(|e| InputsError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "not UTF-8 text (invalid byte at offset {})",
                    e.utf8_error().valid_up_to()
                ),
            ),
        })?;
        Self::parse(&text).map_err(|e| InputsError::InFile {
            path: path.to_path_buf(),
            source: Box::new(e),
        })
    }

    /// Parses CSV text (see the module documentation).
    ///
    /// # Errors
    /// Any [`InputsError`] but `Io`.
    pub fn parse(text: &str) -> Result<Self, InputsError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (_, header) = lines.next().ok_or(InputsError::Empty)?;
        // A UTF-8 byte-order mark (spreadsheets write one) is not part of the first name.
        let header = header.trim_start_matches('\u{feff}').trim();
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        for (k, name) in names.iter().enumerate() {
            if names[..k].iter().any(|n| n.eq_ignore_ascii_case(name)) {
                return Err(InputsError::DuplicateColumn {
                    column: (*name).to_string(),
                });
            }
        }
        let find = |n: &str| names.iter().position(|c| c.eq_ignore_ascii_case(n));
        let (key, key_col) = match (find("frame"), find("t")) {
            (Some(c), None) => (Key::Frame, c),
            (None, Some(c)) => (Key::Time, c),
            _ => {
                return Err(InputsError::Header {
                    what: "exactly one of the key columns `frame` and `t`",
                });
            }
        };
        let v_col = find("v2").ok_or(InputsError::Header {
            what: "a `v2` column",
        })?;
        let w_col = find("w2").ok_or(InputsError::Header {
            what: "a `w2` column",
        })?;
        let pan_col = find("pan");
        let key_name = match key {
            Key::Frame => "frame",
            Key::Time => "t",
        };
        let mut rows: Vec<(f64, InputSample)> = Vec::new();
        for (line, l) in lines {
            let fields: Vec<&str> = l.split(',').map(str::trim).collect();
            if fields.len() != names.len() {
                return Err(InputsError::ShortRow {
                    line,
                    found: fields.len(),
                    expected: names.len(),
                });
            }
            let value = |col: usize| -> Result<f64, InputsError> {
                fields[col]
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| InputsError::BadValue {
                        line,
                        column: names[col].to_string(),
                        value: fields[col].to_string(),
                    })
            };
            let k = match key {
                Key::Frame => fields[key_col]
                    .parse::<u64>()
                    .map(|f| f as f64)
                    .map_err(|_| InputsError::BadFrame {
                        line,
                        value: fields[key_col].to_string(),
                    })?,
                Key::Time => value(key_col)?,
            };
            if let Some((prev, _)) = rows.last()
                && k <= *prev
            {
                return Err(InputsError::NotIncreasing {
                    line,
                    key: key_name,
                    value: k,
                });
            }
            let bounded = |col: usize, bound: f64, range: &'static str| {
                let v = value(col)?;
                if v.abs() <= bound {
                    Ok(v)
                } else {
                    Err(InputsError::OutOfRange {
                        line,
                        column: names[col].to_string(),
                        value: v,
                        range,
                    })
                }
            };
            let sample = InputSample {
                inputs: Inputs::new(
                    bounded(v_col, MAX_SPEED, "-20 to 20 m/s (MAX_SPEED)")?,
                    bounded(w_col, MAX_TURN_RATE, "-20 to 20 rad/s (MAX_TURN_RATE)")?,
                ),
                pan: pan_col
                    .map(|c| bounded(c, std::f64::consts::PI, "-pi to pi rad"))
                    .transpose()?,
            };
            rows.push((k, sample));
        }
        if rows.is_empty() {
            return Err(InputsError::Empty);
        }
        Ok(Self { key, rows })
    }

    /// The key column of the file.
    pub fn key(&self) -> Key {
        self.key
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are no rows (never true for a parsed file).
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The inputs for frame `frame` at time `t`: the last row at or before it, or `None`
    /// before the first row.
    pub fn at(&self, frame: u64, t: f64) -> Option<InputSample> {
        let probe = match self.key {
            Key::Frame => frame as f64,
            Key::Time => t + 1e-6,
        };
        let n = self.rows.partition_point(|(k, _)| *k <= probe);
        n.checked_sub(1).map(|i| self.rows[i].1)
    }
}
