//! Tracking-guided detection: where to look for each leader's markers in the coming frame.
//!
//! The tracker predicts every leader's formation variables `(l12, alpha12, beta12)` for
//! the coming frame ([`Tracker::predict`](crate::tracker::Tracker::predict)). From them
//! the leader's rig is placed on the floor in the follower's body frame (reference point at
//! `l12` from the camera point along `beta12`, heading `beta12 - alpha12`), carried into the
//! camera frame through the mount, and every marker corner of every face is projected with
//! the camera's intrinsics. The bounding box of those points, widened by a margin, is the
//! leader's [`Region`]; the detector then searches only the regions
//! ([`fiducial::Search::regions`]).
//!
//! # Margin
//! The prediction is uncertain, and the margin grows with it: `sigmas` standard deviations
//! of the bearing `beta12` move the rig sideways by `fx sigma_beta` pixels, of the range
//! `l12` scale its image by `sigma_l / l12`; to that come `margin_px` pixels and
//! `margin_rel` of the box's size (lens distortion, the rig's height, a marker's quiet
//! zone). All faces are projected, so the leader's heading needs no margin.
//!
//! # When the whole frame is scanned
//! A region shows only the leaders already tracked, so the pipeline scans the full frame
//! every [`GuidedConfig::full_scan_period`] frames (new robots entering), and also when
//! there is no track, when a track is coasting (it was not found where predicted), or when
//! a prediction does not project into the frame. A periodic scan of a large frame runs at a
//! coarser scale ([`GuidedConfig::coarse_factor`]), which finds the big markers of robots
//! close enough to follow at a fraction of the cost; the corners are still refined at full
//! resolution. A scan after a lost sighting is always at full resolution.
//!
//! Markers that will look large are searched for at a coarser scale inside their region
//! too ([`GuidedConfig::region_px_per_factor`], the "minimum marker size to pyramid level"
//! idea of ArUco 3): at 3840x2160 a leader 1.5 m away shows markers about 270 px tall,
//! whose quads are found on a 4 x 4-averaged copy of the region, then refined at full
//! resolution. A face seen at a grazing angle is as tall but narrow, and averaged it may
//! lose its outline: the boxes of faces narrower than the factor times
//! [`NARROW_PX_PER_FACTOR`] are searched at full resolution as well
//! ([`LeaderRegion::fine_regions`]).

use fiducial::Region;
use nalgebra::Point3;
use pose::Intrinsics;

use crate::mount::CameraMount;
use crate::rig::Face;
use crate::tracker::PredictedLeader;

/// Settings of tracking-guided detection. [`GuidedConfig::default`] documents the defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidedConfig {
    /// A full-frame scan every this many frames, at least (default 10: a third of a second
    /// at 30 frames/s, within which a robot entering the view is picked up).
    pub full_scan_period: u32,
    /// Standard deviations of the prediction covered by the margin (default 3).
    pub sigmas: f64,
    /// Fixed part of the margin, pixels on each side (default 8).
    pub margin_px: f64,
    /// Part of the margin proportional to the projected rig's width and height, on each side
    /// (default 0.25).
    pub margin_rel: f64,
    /// Scale of the periodic full-frame scans: `Some(f)` averages `f x f` blocks (1 to 4);
    /// `None` (the default) chooses from the frame width: 1 below 1920 pixels, 2 from 1920
    /// (at 3840x2160, markers from 20 px are then found by the periodic scan).
    pub coarse_factor: Option<usize>,
    /// Quads in a region are searched at `1 / f` of the resolution, `f` the predicted height
    /// of the leader's markers divided by this many pixels (1 to 4; default 48, so markers
    /// stay at least 48 px tall where quads are searched; corners are still refined at full
    /// resolution). `f64::INFINITY` keeps regions at full resolution.
    pub region_px_per_factor: f64,
}

/// Most narrow faces of one leader kept in [`LeaderRegion::narrow`].
pub const MAX_NARROW: usize = 4;

/// Least projected width, in pixels of the scaled search, of a face searched at a coarser
/// scale ([`LeaderRegion::fine_regions`]): a face seen at a grazing angle is as tall as the
/// others but narrow, and averaged `f x f` its cells fall under about 3 pixels and its dark
/// outline closes no more (on the demo at 3840x2160, factor 4, a face 40 px wide was read by
/// the full scan and missed in the region).
pub const NARROW_PX_PER_FACTOR: f64 = 24.0;

/// Faces narrower than this (pixels, full resolution) are left to chance: no scan reads them
/// reliably (the detector's default `min_side` is 10 px).
const MIN_FACE_PX: f64 = 10.0;

/// A leader's predicted region and how large its markers will look.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderRegion {
    /// Where its markers will be, margin included.
    pub region: Region,
    /// The tallest projected marker side (its vertical edges), pixels.
    pub marker_px: f64,
    /// The narrowest faces turned towards the camera (at least 10 px wide): each face's own
    /// box with a margin (as the region's, its relative part from the face's size), and its
    /// projected width in pixels (the shorter of its
    /// top and bottom edges). Up to [`MAX_NARROW`], narrowest first.
    pub narrow: [Option<(Region, f64)>; MAX_NARROW],
}

impl LeaderRegion {
    /// The boxes of the faces that a search at `factor` could miss (narrower than
    /// `factor` times [`NARROW_PX_PER_FACTOR`]): the caller searches them at full
    /// resolution besides the region. None at factor 1.
    pub fn fine_regions(&self, factor: usize) -> impl Iterator<Item = Region> + '_ {
        self.narrow
            .iter()
            .flatten()
            .filter(move |(_, w)| factor > 1 && *w < factor as f64 * NARROW_PX_PER_FACTOR)
            .map(|(r, _)| *r)
    }

    /// The scale factor of the quad search in this region (see
    /// [`GuidedConfig::region_px_per_factor`]).
    pub fn factor(&self, config: &GuidedConfig) -> usize {
        let f = (self.marker_px / config.region_px_per_factor).floor();
        if f.is_finite() {
            (f as usize).clamp(1, 4)
        } else {
            1
        }
    }
}

impl Default for GuidedConfig {
    fn default() -> Self {
        Self {
            full_scan_period: 10,
            sigmas: 3.0,
            margin_px: 8.0,
            margin_rel: 0.25,
            coarse_factor: None,
            region_px_per_factor: 48.0,
        }
    }
}

/// A guided-mode setting out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GuidedError {
    /// A setting is outside its range.
    #[error("guided detection: {what} is {value}, expected {expected}")]
    Invalid {
        /// The setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
}

impl GuidedConfig {
    /// Checks every setting's range.
    ///
    /// # Errors
    /// [`GuidedError::Invalid`] naming the first bad setting.
    pub fn validate(&self) -> Result<(), GuidedError> {
        let bad = |what, value: f64, expected| GuidedError::Invalid {
            what,
            value,
            expected,
        };
        if self.full_scan_period == 0 {
            return Err(bad("full_scan_period", 0.0, "at least 1"));
        }
        for (what, v) in [
            ("sigmas", self.sigmas),
            ("margin_px", self.margin_px),
            ("margin_rel", self.margin_rel),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(what, v, "finite and >= 0"));
            }
        }
        if self.region_px_per_factor.is_nan() || self.region_px_per_factor <= 0.0 {
            return Err(bad(
                "region_px_per_factor",
                self.region_px_per_factor,
                "positive (infinite: full resolution)",
            ));
        }
        if let Some(f) = self.coarse_factor
            && !(1..=4).contains(&f)
        {
            return Err(bad("coarse_factor", f as f64, "1 to 4"));
        }
        Ok(())
    }

    /// The scale factor of a periodic full scan of a frame `width` pixels wide.
    pub fn coarse_factor_for(&self, width: usize) -> usize {
        self.coarse_factor
            .unwrap_or(if width >= 1920 { 2 } else { 1 })
            .clamp(1, 4)
    }
}

/// The image region where `leader`'s markers will be in a `width x height` frame (see the
/// module documentation), or `None` when no marker corner of `faces` projects in front of
/// the camera or the box misses the frame.
pub fn leader_region(
    leader: &PredictedLeader,
    faces: &[Face],
    mount: &CameraMount,
    camera: &Intrinsics,
    size: (usize, usize),
    config: &GuidedConfig,
) -> Option<LeaderRegion> {
    let [l12, alpha12, beta12]: [f64; 3] = leader.formation.into();
    let x = mount.offset + l12 * beta12.cos();
    let y = l12 * beta12.sin();
    let (rotation, translation) = mount.leader_to_camera(x, y, beta12 - alpha12);
    // The rig's box `[u0, v0, u1, v1]` over every corner projected.
    let mut rig = EMPTY_BOX;
    let mut marker_px = 0.0f64;
    // Narrow front faces: box (u0, v0, u1, v1) and width, narrowest first.
    let mut narrow: [Option<([f64; 4], f64)>; MAX_NARROW] = [None; MAX_NARROW];
    for face in faces {
        let mut projected = [None; 4];
        for (slot, c) in projected.iter_mut().zip(face.corners) {
            let p = rotation * Point3::from(c) + translation;
            // Points behind or very near the camera plane project nowhere useful.
            if p.z < 0.05 {
                continue;
            }
            let Ok(m) = camera.project(&p) else {
                continue;
            };
            rig = grow(rig, &m);
            *slot = Some(m);
        }
        // The vertical edges (NW-SW, NE-SE): their length does not shrink with the face's
        // obliquity.
        for (a, b) in [(0, 3), (1, 2)] {
            if let (Some(p), Some(q)) = (projected[a], projected[b]) {
                marker_px = marker_px.max((p - q).norm());
            }
        }
        // A face turned towards the camera (its outward normal against the line of sight)
        // and narrow in the image is kept with its own box.
        let centre = rotation * Point3::from(face.centre) + translation;
        let normal = rotation * nalgebra::Vector3::from(face.normal);
        if let [Some(nw), Some(ne), Some(se), Some(sw)] = projected
            && normal.dot(&centre.coords) < 0.0
        {
            let width = (ne - nw).norm().min((se - sw).norm());
            if width >= MIN_FACE_PX {
                let bounds = [nw, ne, se, sw].iter().fold(EMPTY_BOX, grow);
                keep_narrowest(&mut narrow, (bounds, width));
            }
        }
    }
    let [u0, v0, u1, v1] = rig;
    if !(u0.is_finite() && u1.is_finite() && v0.is_finite() && v1.is_finite()) {
        return None;
    }
    let [sl, _, sb]: [f64; 3] = leader.std.into();
    let scale = config.sigmas * sl / l12.max(1e-3);
    // The box `[u0, v0, u1, v1]` widened by the margin, cut to the frame (a wildly
    // uncertain prediction gives a huge region).
    let widened = |[u0, v0, u1, v1]: [f64; 4]| {
        let mx = config.sigmas * camera.alpha() * sb
            + (0.5 * scale + config.margin_rel) * (u1 - u0)
            + config.margin_px;
        let my = (0.5 * scale + config.margin_rel) * (v1 - v0) + config.margin_px;
        Region::from_bounds(u0 - mx, v0 - my, u1 + mx, v1 + my, size.0, size.1)
    };
    let region = widened([u0, v0, u1, v1])?;
    // A narrow face's box takes the same margin, its relative part from the face's own size.
    let narrow = narrow.map(|n| n.and_then(|(bounds, w)| widened(bounds).map(|r| (r, w))));
    Some(LeaderRegion {
        region,
        marker_px,
        narrow,
    })
}

/// The box `[u0, v0, u1, v1]` holding nothing, which [`grow`] extends.
const EMPTY_BOX: [f64; 4] = [
    f64::INFINITY,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NEG_INFINITY,
];

/// The box `[u0, v0, u1, v1]` grown to hold `p`.
fn grow([u0, v0, u1, v1]: [f64; 4], p: &nalgebra::Point2<f64>) -> [f64; 4] {
    [u0.min(p.x), v0.min(p.y), u1.max(p.x), v1.max(p.y)]
}

/// Inserts `face` (box, width) into `narrow`, kept sorted narrowest first; the widest falls
/// out when it is full.
fn keep_narrowest(narrow: &mut [Option<([f64; 4], f64)>; MAX_NARROW], face: ([f64; 4], f64)) {
    let mut item = Some(face);
    for slot in narrow.iter_mut() {
        match (*slot, item) {
            (None, _) => {
                *slot = item;
                return;
            }
            (Some(s), Some(f)) if f.1 < s.1 => {
                *slot = Some(f);
                item = Some(s);
            }
            _ => {}
        }
    }
}
