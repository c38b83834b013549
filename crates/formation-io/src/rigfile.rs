//! Rig files: a YAML or JSON description of the marker rig that overrides the reference rig
//! of spec 3.3 (faces, their geometry, and the dictionary entry on each `(robot, face)`).
//!
//! Every field is optional; what is left out keeps its reference value, so an empty file
//! (`{}`) *is* the reference rig. Unknown fields are errors (a misspelt `cell_size_mm` must not
//! silently fall back to the default), and every semantic check names the offending field,
//! e.g. `faces[2].yaw_deg`.
//!
//! ```yaml
//! dictionary: FORMATION_4X5     # or tag36h11, DICT_6X6_250, ... (fiducial::standard)
//! face_width_m: 0.18            # octagon face width
//! marker_centre_height_m: 0.30  # marker centres above the ground
//! cell_size_m: 0.02             # one marker cell
//! data_rows: 4
//! data_cols: 5
//! faces:                        # default: faces 1..5 at yaw 90, 135, 180, -135, -90 deg
//!   - { face: 1, yaw_deg: 90 }
//!   - { face: 3, yaw_deg: 180 }
//! markers:                      # default: entry (robot - 1) * faces + position of face
//!   - { robot: 1, face: 1, index: 40 }
//!   - { robot: 1, face: 3, code: 663209 }
//!   - { robot: 2, face: 1, dictionary: FORMATION_4X5, id: 7 }   # (dictionary, id)
//! ```
//!
//! Faces sit on the octagon (centred over the robot's reference point, at the apothem of
//! the face width) with outward normals at `yaw_deg` in the robot's body frame; two faces must
//! be at least 45 degrees apart so they cannot overlap. When `markers` is given it is the
//! complete table: a `(robot, face)` not listed carries no marker.

use std::path::Path;

use fiducial::Dictionary;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use formation_tracker::rig::{FaceSpec, RigError, RigGeometry, RigModel};

use crate::textfile;

/// What is wrong with a rig file.
#[derive(Debug, Error)]
pub enum RigFileError {
    /// The file could not be read.
    #[error("cannot read rig file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not valid YAML/JSON for a rig (syntax, unknown or mistyped field).
    #[error("rig file {path}: {message}")]
    Parse {
        /// The file (or `<string>`).
        path: String,
        /// The parser's message, naming the field and position.
        message: String,
    },
    /// A field has a value that makes no rig.
    #[error("rig file: field `{field}`: {reason}")]
    Field {
        /// The field, e.g. `faces[2].yaw_deg`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The geometry is invalid (lengths, marker family, marker too wide).
    #[error(transparent)]
    Rig(#[from] RigError),
}

/// One `(robot, face)` -> marker assignment of a rig file: a dictionary entry (`index`, or
/// `id` with an optional `dictionary`, i.e. `(dictionary, id)`) or the `code` itself (looked
/// up in the dictionary).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerSpec {
    /// Robot number, from 1.
    pub robot: u32,
    /// Face number, one of the rig's faces.
    pub face: u8,
    /// The marker's dictionary (any accepted name); must be the rig's `dictionary`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dictionary: Option<String>,
    /// The marker's id in that dictionary (same as `index`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<usize>,
    /// Dictionary entry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<usize>,
    /// The code (alternative to `index`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub code: Option<u64>,
}

/// The rig file as written: every field optional.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    /// The dictionary of the rig's markers, by name (default: our own, `FORMATION_4X5`;
    /// e.g. `tag36h11`, `DICT_6X6_250`; case-insensitive). `data_rows`/`data_cols` default
    /// to its grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dictionary: Option<String>,
    /// Width of each face, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub face_width_m: Option<f64>,
    /// Height of the marker centres, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marker_centre_height_m: Option<f64>,
    /// Side of one marker cell, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_size_m: Option<f64>,
    /// Rows of data cells.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_rows: Option<u32>,
    /// Columns of data cells.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_cols: Option<u32>,
    /// The faces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faces: Option<Vec<FaceSpec>>,
    /// The marker table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers: Option<Vec<MarkerSpec>>,
}

/// Parses and checks a rig file's text; `json` selects the JSON parser (otherwise YAML,
/// which also reads JSON). `path` only labels error messages.
///
/// # Errors
/// The parser's message, or the first field that fails its check.
pub fn from_text(
    text: &str,
    json: bool,
    path: &str,
    dictionary: &Dictionary,
) -> Result<RigModel, RigFileError> {
    let file: RigFile = if !json && text.trim().is_empty() {
        RigFile::default()
    } else {
        textfile::parse(text, json).map_err(|message| RigFileError::Parse {
            path: path.to_string(),
            message,
        })?
    };
    from_file(&file, dictionary)
}

/// Reads a rig file (`.json` is parsed as JSON, anything else as YAML).
///
/// # Errors
/// The file cannot be read (or is over [`textfile::MAX_TEXT_BYTES`]); as [`from_text`].
pub fn load(path: &Path, dictionary: &Dictionary) -> Result<RigModel, RigFileError> {
    let (text, json) = textfile::read(path).map_err(|source| RigFileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    from_text(&text, json, &path.display().to_string(), dictionary)
}

/// Checks a parsed rig file and fills in the reference values.
///
/// `dictionary` is the one the caller reads with; a file that names its own
/// `dictionary` uses that one instead.
///
/// # Errors
/// The first field that fails its check.
pub fn from_file(file: &RigFile, dictionary: &Dictionary) -> Result<RigModel, RigFileError> {
    let (dictionary, name) = match &file.dictionary {
        Some(name) => {
            let d = fiducial::dictionary_by_name(name)
                .map_err(|e| field("dictionary", e.to_string()))?;
            (d, d.name().unwrap_or(fiducial::PAPER_NAME))
        }
        None => (
            dictionary,
            dictionary.name().unwrap_or(fiducial::PAPER_NAME),
        ),
    };
    let mut r = RigGeometry::reference();
    if file.dictionary.is_some() {
        r.data_rows = dictionary.family().rows();
        r.data_cols = dictionary.family().cols();
    }
    let geometry = RigGeometry {
        face_width_m: file.face_width_m.unwrap_or(r.face_width_m),
        marker_centre_height_m: file
            .marker_centre_height_m
            .unwrap_or(r.marker_centre_height_m),
        cell_size_m: file.cell_size_m.unwrap_or(r.cell_size_m),
        data_rows: file.data_rows.unwrap_or(r.data_rows),
        data_cols: file.data_cols.unwrap_or(r.data_cols),
    };
    geometry.validate()?;
    let family = geometry.family()?;
    if family != dictionary.family() {
        return Err(field(
            "data_rows/data_cols",
            format!(
                "the rig's markers have {} x {} data cells but the dictionary's have {} x {}",
                family.rows(),
                family.cols(),
                dictionary.family().rows(),
                dictionary.family().cols()
            ),
        ));
    }
    let faces = file
        .faces
        .clone()
        .unwrap_or_else(|| RigModel::reference().faces);
    check_faces(&faces)?;
    let markers = match &file.markers {
        None => None,
        Some(list) => Some(check_markers(list, &faces, dictionary, name)?),
    };
    Ok(RigModel {
        geometry,
        faces,
        markers,
        dictionary: name,
    })
}

fn field(name: impl Into<String>, reason: impl Into<String>) -> RigFileError {
    RigFileError::Field {
        field: name.into(),
        reason: reason.into(),
    }
}

fn check_faces(faces: &[FaceSpec]) -> Result<(), RigFileError> {
    if faces.is_empty() {
        return Err(field("faces", "a rig needs at least one face"));
    }
    if faces.len() > 8 {
        return Err(field(
            "faces",
            format!("an octagon has at most 8 faces, got {}", faces.len()),
        ));
    }
    for (i, f) in faces.iter().enumerate() {
        if f.face == 0 {
            return Err(field(format!("faces[{i}].face"), "face numbers start at 1"));
        }
        if !f.yaw_deg.is_finite() {
            return Err(field(
                format!("faces[{i}].yaw_deg"),
                format!("must be a finite angle in degrees, got {}", f.yaw_deg),
            ));
        }
        for (j, g) in faces[..i].iter().enumerate() {
            if g.face == f.face {
                return Err(field(
                    format!("faces[{i}].face"),
                    format!("face {} is already faces[{j}]", f.face),
                ));
            }
            let gap = unicycle::wrap_angle((f.yaw_deg - g.yaw_deg).to_radians()).abs();
            if gap.to_degrees() < 45.0 - 1e-9 {
                return Err(field(
                    format!("faces[{i}].yaw_deg"),
                    format!(
                        "{} deg is {:.1} deg from faces[{j}] ({} deg); octagon faces must be at \
                         least 45 deg apart",
                        f.yaw_deg,
                        gap.to_degrees(),
                        g.yaw_deg
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn check_markers(
    list: &[MarkerSpec],
    faces: &[FaceSpec],
    dictionary: &Dictionary,
    name: &str,
) -> Result<Vec<(u32, u8, usize)>, RigFileError> {
    let mut out: Vec<(u32, u8, usize)> = Vec::with_capacity(list.len());
    for (i, m) in list.iter().enumerate() {
        if let Some(d) = &m.dictionary {
            let canonical = fiducial::canonical_name(d)
                .map_err(|e| field(format!("markers[{i}].dictionary"), e.to_string()))?;
            if canonical != name {
                return Err(field(
                    format!("markers[{i}].dictionary"),
                    format!(
                        "`{d}` is not the rig's dictionary {name} (set the top-level                          `dictionary`; one rig reads one dictionary)"
                    ),
                ));
            }
        }
        let index = match (m.index, m.id) {
            (Some(_), Some(_)) => {
                return Err(field(
                    format!("markers[{i}]"),
                    "give either `index` or `id`, not both",
                ));
            }
            (a, b) => a.or(b),
        };
        if m.robot == 0 {
            return Err(field(
                format!("markers[{i}].robot"),
                "robot numbers start at 1",
            ));
        }
        if !faces.iter().any(|f| f.face == m.face) {
            return Err(field(
                format!("markers[{i}].face"),
                format!("the rig has no face {}", m.face),
            ));
        }
        let index = match (index, m.code) {
            (Some(index), None) => {
                if index >= dictionary.len() {
                    return Err(field(
                        format!("markers[{i}].index"),
                        format!(
                            "entry {index} is beyond the dictionary's {} entries",
                            dictionary.len()
                        ),
                    ));
                }
                index
            }
            (None, Some(code)) => dictionary.index_of(code).ok_or_else(|| {
                field(
                    format!("markers[{i}].code"),
                    format!("code {code} is not in the dictionary"),
                )
            })?,
            (Some(_), Some(_)) => {
                return Err(field(
                    format!("markers[{i}]"),
                    "give either `index`/`id` or `code`, not both",
                ));
            }
            (None, None) => {
                return Err(field(
                    format!("markers[{i}]"),
                    "needs an `id` (dictionary entry; `index` also works) or a `code`",
                ));
            }
        };
        if let Some(j) = out
            .iter()
            .position(|&(r, f, _)| r == m.robot && f == m.face)
        {
            return Err(field(
                format!("markers[{i}]"),
                format!(
                    "robot {} face {} is already given by markers[{j}]",
                    m.robot, m.face
                ),
            ));
        }
        if let Some(j) = out.iter().position(|&(_, _, k)| k == index) {
            return Err(field(
                format!("markers[{i}]"),
                format!("dictionary entry {index} is already used by markers[{j}]"),
            ));
        }
        out.push((m.robot, m.face, index));
    }
    Ok(out)
}
