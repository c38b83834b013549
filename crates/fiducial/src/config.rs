//! Every tunable of the detector, in one struct with documented defaults.

use crate::decode::DecodeParams;
use crate::refine::RefineConfig;
use crate::sides::SideCheck;
use crate::threshold::Threshold;

/// Every tunable of the detector, with documented defaults ([`DetectorConfig::default`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorConfig {
    /// Binarization (default: adaptive tiles of 8 px, minimum contrast 30).
    pub threshold: Threshold,
    /// Shortest marker side in pixels (default 10).
    pub min_side: f64,
    /// Smallest interior corner angle in degrees, allowing for perspective (default 15).
    ///
    /// A marker lying almost flat, seen at a grazing angle, is a thin parallelogram with two
    /// sharp corners: 20.5 degrees for tag 8 of the NASA photo (`shared/realdata/nasa`), 24
    /// degrees for id 24 of the Duckietown frame `test_image_multiple_09.png`. At 30 (the
    /// default until 2026-12-07) the first pass refused them and only boundary clustering
    /// (off by default, [`DetectorConfig::boundary_clusters`]) read them; AprilTag 3 accepts
    /// corners down to 10 degrees. At 15 (boundary clustering's own limit,
    /// `fiducial::cluster`) the default detector reads 55 of the 56 Duckietown tags (52 at
    /// 30) and 2 more tags of the NASA photo, with no read on the marker-free photos in any
    /// family and the same reads on the synthetic scenes (`docs/marker-families.md`).
    pub min_angle_deg: f64,
    /// Straightness tolerance of a side: absolute pixels (default 1.5)...
    pub line_tolerance: f64,
    /// ...plus this fraction of the side length (default 0.05).
    pub line_tolerance_rel: f64,
    /// Components closer than this many pixels to the frame border are rejected (default 2).
    pub border_margin: u32,
    /// Sub-pixel refinement settings (default: [`RefineConfig::default`]).
    pub refine: RefineConfig,
    /// Decoding settings (default: [`DecodeParams::default`] but with soft-decision instead
    /// of hard bit correction and samples over +-0.1 cell, see [`DetectorConfig::default`]).
    pub decode: DecodeParams,
    /// Read a quad whose sampled cells are not an entry once more as a motion-blurred
    /// marker (blur estimated from its edges, cell levels solved by least squares; issue
    /// #16). Default on: only quads whose plain reading had a marker's contrast and dark
    /// border, and whose edges show a motion of at least 1.5 cells that smears the outline
    /// outwards, are re-read (counted by
    /// [`crate::DetectStats::blurred`]); its systems are solved in scratch the detector owns (no
    /// allocation in steady state), and a marker it reads passes the side check like any
    /// other. With it on, the boxes of dark components that gave no quad (up to 160 px)
    /// are also cut nearer the white level, where a marker smeared by two cells or more
    /// still has a closed outline ([`crate::Detector`]'s light cut).
    pub motion_blur: bool,
    /// Drop a decoded marker one of whose sides is not its border's outer edge, as when the
    /// side runs along an occluder (the crate's side check, issue #16), measured on the
    /// plain corners and, when that fails, on the corners fitted to the decoded pattern (a
    /// tag seen obliquely in a real photo has borders of 2-3 px, where the plain corners'
    /// grid can be a few tenths of a pixel off; issue #31). Default on, with
    /// [`SideCheck::default`]; `None` turns it off.
    pub side_check: Option<SideCheck>,
    /// Look for quads in the boundary clusters of large dark components that gave no quad
    /// (AprilTag 3's quad search, the second look's boundary clusters; issue #13): finds markers whose border has
    /// merged with something as dark as their ink, e.g. flat tags at grazing angles on real
    /// frames (it reads the one Duckietown tag of 56 the first pass misses). Default off here (the
    /// per-frame loop of a robot; `formation-tracker detect` turns it on): it labels the
    /// boxes of every large component that gave no quad, often most of a real or
    /// cluttered frame (measured on one core: 640x480 clutter frames 2.2-6.1 ms a frame
    /// without it, 9.5-13.1 ms with it; the 11 Duckietown frames 2.0 ms a frame without,
    /// 5.6 ms with; nothing on the synthetic marker scenes, whose dark components are all
    /// quads).
    pub boundary_clusters: bool,
}

impl DetectorConfig {
    /// The defaults, with the photometric step on markers whose cells are under
    /// [`crate::PHOTOMETRIC_BELOW_PX`] ([`RefineConfig::photometric_below_px`]): the settings
    /// of a robot that measures its distance to small, distant markers (the `formation-tracker`
    /// pipeline). There the edge rules' bias of small cells is a bias of the pose: on the
    /// `far` scenario (cells of 2-3 px at 3.5 m) it put `l12` 12.8 mm long, fitted it is
    /// within 0.2 mm. It costs 0.5-2 ms per marker fitted. The plain default leaves it off:
    /// on the real frames we have, where AprilTag 3's corners are the only reference, it
    /// changed nothing measurable (the 56 Duckietown tags' RMS distance to them 0.211 px
    /// without, 0.218 px with) and doubled the detection time (`docs/performance.md`).
    pub fn for_pose() -> Self {
        let mut config = Self::default();
        config.refine.photometric_below_px = crate::PHOTOMETRIC_BELOW_PX;
        config
    }
}

impl Default for DetectorConfig {
    /// The defaults documented on each field.
    ///
    /// Hard bit correction is off (`decode.max_errors = 0`): a black-bordered square with
    /// random content lies within two bits of one of the paper dictionary's 100 codes (in
    /// either orientation) with probability about 4 %, within one bit about 0.4 %, so in
    /// cluttered scenes hard correction invents markers (`docs/detector-accuracy.md` counts
    /// them: 1-bit correction read 8 codes in 1000 clutter frames, 2-bit 79).
    ///
    /// Soft-decision correction is on (`decode.soft_errors = 2`, `decode.soft_margin =
    /// 0.3`): a reading may have its one or two *least confident* cells flipped, each only if
    /// its level is within 0.3 of half the contrast from the threshold, and the result must
    /// then be an entry exactly. Real markers that misread do so in a cell at the threshold
    /// (all 6 markers lost on the accuracy scenes without it were ~20 px markers, cells of
    /// ~3 px under blur 1, with one wrong bit of margin below 0.12), while a clutter square
    /// or a foreign marker that is one bit from an entry is so in a confident cell. On the
    /// accuracy scenes this finds 1600/1600 markers with no false read in 1000 clutter
    /// frames or 800 foreign markers.
    ///
    /// Cells are sampled over +-0.1 cell rather than +-0.25: on the smallest markers (cells
    /// of about 3 px, blur sigma 1) the wider square reaches into the blur of neighbouring
    /// cells, and 8 of 9 markers lost on the accuracy scenes were such misreads.
    fn default() -> Self {
        Self {
            threshold: Threshold::default(),
            min_side: 10.0,
            min_angle_deg: 15.0,
            line_tolerance: 1.5,
            line_tolerance_rel: 0.05,
            border_margin: 2,
            refine: RefineConfig::default(),
            decode: DecodeParams {
                max_errors: 0,
                sample_radius: 0.1,
                soft_errors: 2,
                soft_margin: 0.3,
                ..DecodeParams::default()
            },
            motion_blur: true,
            side_check: Some(SideCheck::default()),
            boundary_clusters: false,
        }
    }
}
