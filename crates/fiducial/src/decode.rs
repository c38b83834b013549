//! Reading a marker's code from an image, given its four refined corners (spec 3.4 step 4).
//!
//! Every cell centre is found by the cross-ratio construction ([`crate::cross_ratio`]) and
//! the grey level around it is averaged over a small square (bilinear samples; samples
//! outside the image are skipped) whose half-size is a fraction of the cell pitch measured
//! from the quad's side lengths, so the same code reads a 20-pixel and a 200-pixel marker.
//!
//! The border ring gives the black reference, the ring of quiet-zone cells just outside it
//! the white reference (medians, so a few bad cells do not move them). Markers printed
//! without a white margin (the standard ArUco/AprilTag families,
//! [`WhiteReference::DataCells`]) take white from their own light data cells instead. Their difference is
//! the contrast; a data cell is black when darker than the midpoint. A quad is rejected
//! when the contrast is too low, when more than a few border cells read light (the border
//! must be dark), or when the code is not within the dictionary's correction radius.
//!
//! Orientation. The corners may start at any of the marker's corners (clockwise in the
//! image). For a square family one reading suffices: the dictionary lookup tries all four
//! rotations. A non-square `m x n` grid maps onto itself only under half turns, so the grid
//! is read twice, with the corners as given and shifted by one; the reading whose samples
//! fall most cleanly inside cells ([`CellReading::fit`]: samples of a grid read across the
//! wrong aspect land on cell boundaries) is the one looked up. Choosing the aspect *before*
//! the lookup keeps the guarantee that three flipped bits never give a wrong ID. The result carries the rotation found
//! and the corners re-ordered into the marker's own NW, NE, SE, SW.
//!
//! Soft-decision correction. Hard correction ([`DecodeParams::max_errors`]) accepts any
//! entry within that many bits, however clearly the disagreeing cells were read; on random
//! dark-bordered clutter it invents markers. The decoder also knows how confident each bit
//! is: a cell's *margin* is its distance from the threshold over half the contrast
//! ([`CellReading::margin`]). The soft decision ([`DecodeParams::soft_errors`] `= k`,
//! [`DecodeParams::soft_margin`] `= t`) is an erasure decode: when the reading is not an
//! entry, the `k` least confident cells whose margin is below `t` are treated as unknown,
//! each subset of them is flipped (fewest flips first) and the result must be an entry
//! *exactly*. So an entry is accepted at Hamming distance 1 or 2 only if every disagreeing
//! cell was among the `k` weakest of the reading and within `t` of the threshold; a reading
//! that disagrees with every entry in some confident cell is rejected. `k` is capped at the
//! dictionary's `(d_min - 1) / 2`, so a soft read is still never at distance `>= d_min / 2`
//! and is the unique entry that close. The detector uses `k = 2`, `t = 0.3` and no hard
//! correction (see [`crate::DetectorConfig::default`] for the measurements behind them).
//!
//! Nothing here allocates: cell levels live in fixed arrays and the code in a `u64`.

use crate::cross_ratio::{CrossRatioFrame, convex_quad_area2};
use crate::dictionary::Dictionary;
use crate::family::MarkerFamily;
use crate::image::{Corners, GrayView};

/// Tuning of [`decode`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeParams {
    /// Most bit errors to correct; capped at the dictionary's `(d_min - 1) / 2`.
    pub max_errors: u32,
    /// Smallest accepted difference between the white (quiet zone) and black (border)
    /// reference levels, in grey levels.
    pub min_contrast: f64,
    /// Most border cells allowed to read light (above the midpoint).
    pub max_light_border_cells: u32,
    /// Half-size of the averaged square around each cell centre, as a fraction of the
    /// smallest measured cell pitch (0 samples only the centre; at most 0.5).
    pub sample_radius: f64,
    /// Soft-decision correction: most bits that may be flipped among the *least confident*
    /// cells of a reading (erasure-style decoding, see the module docs); capped at the
    /// dictionary's `(d_min - 1) / 2`. 0 turns soft decisions off.
    pub soft_errors: u32,
    /// Soft-decision correction: a cell may be flipped only if its level is closer to the
    /// threshold than this fraction of half the contrast (its normalised margin, 0 = on the
    /// threshold, 1 = as dark or light as the references).
    pub soft_margin: f64,
}

impl Default for DecodeParams {
    /// Full (hard) correction, contrast >= 20 grey levels, at most 1 light border cell,
    /// samples over +-0.25 cell, no soft decisions (full hard correction already covers
    /// them).
    fn default() -> Self {
        Self {
            max_errors: u32::MAX,
            min_contrast: 20.0,
            max_light_border_cells: 1,
            sample_radius: 0.25,
            soft_errors: 0,
            soft_margin: 0.0,
        }
    }
}

/// Why a quad was not read as a marker. Rejection is the decoder's normal outcome for
/// candidates that are not markers; the variants say which test failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// The corners are not finite or do not form a convex, non-degenerate quadrilateral.
    #[error("not a convex quadrilateral: {reason}")]
    BadQuad {
        /// What is wrong.
        reason: &'static str,
    },
    /// The corners run counter-clockwise in the image (NW, NE, SE, SW must be clockwise
    /// with v pointing down); a mirrored marker is never read.
    #[error("corners run counter-clockwise in the image (see fiducial::clockwise)")]
    CounterClockwise,
    /// A border or data cell has no sample inside the image.
    #[error("a marker cell lies outside the image")]
    OutsideImage,
    /// No quiet-zone sample lies inside the image, so there is no white reference.
    #[error("the quiet zone lies outside the image")]
    QuietZoneOutside,
    /// The quiet zone is not lighter than the border by enough.
    #[error("contrast {contrast:.1} grey levels is below the minimum {min:.1}")]
    LowContrast {
        /// White minus black reference level.
        contrast: f64,
        /// The minimum asked for.
        min: f64,
    },
    /// Too many border cells read light: the border is not dark.
    #[error("{light} border cells read light (at most {max} allowed)")]
    BorderNotDark {
        /// Border cells above the midpoint.
        light: u32,
        /// The maximum allowed.
        max: u32,
    },
    /// The code read is not within the correction radius of any entry.
    #[error("code {read:#x} is {nearest} bits from the nearest entry (at most {max} corrected)")]
    NoMatch {
        /// The code as read, in the corner order given.
        read: u64,
        /// Distance to the nearest entry under any rotation.
        nearest: u32,
        /// The correction limit used.
        max: u32,
    },
    /// Invalid parameters.
    #[error("bad decode parameters: {reason}")]
    BadParams {
        /// What is wrong.
        reason: &'static str,
    },
}

/// The grid read from an image in a given corner order, before lookup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellReading {
    /// The data bits as read, bit `row * n + col` in the frame of the corners given.
    pub code: u64,
    /// Black reference: median level of the border cells.
    pub black: f64,
    /// White reference: median level of the quiet-zone cells inside the image.
    pub white: f64,
    /// Border cells above the midpoint.
    pub light_border_cells: u32,
    /// Smallest distance of a data cell's level from the midpoint, over half the contrast
    /// (1 = every cell as dark or light as the references, 0 = a cell exactly at the
    /// threshold).
    pub confidence: f64,
    /// Mean over data cells of the same normalised margin (each capped at 1), leaving out
    /// the [`DecodeParams::soft_errors`] lowest: how cleanly the sample squares fall inside
    /// cells. A grid read with the wrong aspect (a
    /// non-square marker read across) puts samples on cell boundaries and scores lower.
    pub fit: f64,
    /// Averaged grey level of each data cell, index `row * n + col` as the bits of
    /// [`CellReading::code`] (entries past `m n` are 0).
    pub levels: [f64; 64],
}

impl CellReading {
    /// White minus black reference level.
    pub fn contrast(&self) -> f64 {
        self.white - self.black
    }

    /// Normalised margin of data cell `k`: its distance from the midpoint threshold over
    /// half the contrast (0 = on the threshold, 1 = as dark or light as the references;
    /// may exceed 1).
    pub fn margin(&self, k: usize) -> f64 {
        let half = 0.5 * self.contrast();
        let level = self.levels.get(k).copied().unwrap_or(f64::NAN);
        (level - 0.5 * (self.black + self.white)).abs() / half
    }

    /// The `K` data cells of a grid of `cells` with the smallest margins, weakest first
    /// (fewer if the grid is smaller), as (cell index, margin).
    fn weakest<const K: usize>(&self, cells: usize) -> ([(usize, f64); K], usize) {
        let mut out = [(0usize, f64::INFINITY); K];
        let mut n = 0;
        for k in 0..cells.min(64) {
            let m = self.margin(k);
            // Insertion into the sorted prefix.
            let mut i = n.min(K);
            if i == K && m >= out[K - 1].1 {
                continue;
            }
            if i == K {
                i = K - 1;
            }
            while i > 0 && m < out[i - 1].1 {
                out[i] = out[i - 1];
                i -= 1;
            }
            out[i] = (k, m);
            n = (n + 1).min(K);
        }
        (out, n)
    }
}

/// A marker read from an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decoded {
    /// Which dictionary the marker was read from: its position in the detector's list
    /// ([`crate::Detector::dictionaries`]); always 0 from [`decode`].
    pub dictionary: usize,
    /// Index of the entry in the dictionary: the marker's id.
    pub index: usize,
    /// The entry's code (marker orientation).
    pub code: u64,
    /// Bit errors corrected.
    pub distance: u32,
    /// Clockwise quarter turns of the marker relative to the corner order given: the
    /// marker's own NW corner is input corner `rotation` (so `corners[i] ==
    /// input[(i + rotation) % 4]`).
    pub rotation: u8,
    /// The input corners re-ordered into the marker's own NW, NE, SE, SW.
    pub corners: Corners,
    /// White minus black reference level, in grey levels.
    pub contrast: f64,
    /// See [`CellReading::confidence`].
    pub confidence: f64,
}

/// Samples per cell are at most `(2 MAX_STEPS + 1)^2`: a 5 x 5 grid of bilinear samples
/// spread over the averaging square (about one sample per pixel up to 10-pixel cells,
/// sparser beyond, where the image is anyway far above the noise).
const MAX_STEPS: i32 = 2;

/// Upper bounds of the fixed arrays (8 x 8 data cells, a 10 x 10 marker).
const MAX_BORDER: usize = 4 * 10;
const MAX_QUIET: usize = 4 * 12;

/// Bilinear grey level at `(x, y)`, `None` outside `[0, w-1] x [0, h-1]`.
#[inline]
pub(crate) fn bilinear(image: &GrayView<'_>, x: f64, y: f64) -> Option<f64> {
    let (w, h) = (image.width(), image.height());
    if !(x >= 0.0 && y >= 0.0 && x <= image.max_x() && y <= image.max_y()) {
        return None;
    }
    // Non-negative here, so truncation is floor (and cheaper than its software call; a
    // signed cast is one instruction, an unsigned one several).
    let (x0, y0) = (x as i64, y as i64);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let (x0, y0) = (x0 as usize, y0 as usize);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let (r0, r1) = (image.row(y0), image.row(y1));
    let top = f64::from(r0[x0]) * (1.0 - fx) + f64::from(r0[x1]) * fx;
    let bottom = f64::from(r1[x0]) * (1.0 - fx) + f64::from(r1[x1]) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

/// Samples and averages the grey levels around cells of one quad frame.
struct Sampler<'v, 'a> {
    image: &'v GrayView<'a>,
    frame: CrossRatioFrame,
    width: f64,
    height: f64,
    radius: f64,
    steps: i32,
}

impl Sampler<'_, '_> {
    /// Mean level around the centre of marker cell `(x, y)` (border cells at 0 and
    /// `width - 1`; the quiet zone at -1 and `width`), `None` if no sample is inside.
    fn cell(&self, x: i32, y: i32) -> Option<f64> {
        let (a, b) =
            CrossRatioFrame::cell_coords(f64::from(x), f64::from(y), self.width, self.height);
        let c = self.frame.map(a, b)?;
        let step = if self.steps > 0 {
            self.radius / f64::from(self.steps)
        } else {
            0.0
        };
        square_mean(self.image, [c.x, c.y], step, self.steps.clamp(0, MAX_STEPS))
    }
}

/// The mean of the bilinear levels at `centre + (i, j) step`, `i` and `j` in `-k ..= k`
/// (`k` at most [`MAX_STEPS`]), over those inside the image; `None` if none is.
fn square_mean(img: &GrayView<'_>, centre: [f64; 2], step: f64, k: i32) -> Option<f64> {
    let at = |c: f64, i: i32| c + f64::from(i) * step;
    let [cx, cy] = centre;
    if !(img.within(at(cx, -k), at(cy, -k)) && img.within(at(cx, k), at(cy, k))) {
        return square_mean_checked(img, centre, step, k);
    }
    // Every sample inside with a right and a lower neighbour: the columns' pixels and
    // weights once for all rows, each row's once for its samples (the same values and
    // sums as `square_mean_checked`, in the same order).
    let mut cols = [(0usize, 0.0f64); 2 * MAX_STEPS as usize + 1];
    for (col, i) in cols.iter_mut().zip(-k..=k) {
        let x = at(cx, i);
        let x0 = x as i64;
        *col = (x0 as usize, x - x0 as f64);
    }
    let cols = &cols[..(2 * k + 1) as usize];
    let mut sum = 0.0;
    for j in -k..=k {
        let y = at(cy, j);
        let y0 = y as i64;
        let fy = y - y0 as f64;
        let (r0, r1) = (img.row(y0 as usize), img.row(y0 as usize + 1));
        for &(x0, fx) in cols {
            let top = f64::from(r0[x0]) * (1.0 - fx) + f64::from(r0[x0 + 1]) * fx;
            let bottom = f64::from(r1[x0]) * (1.0 - fx) + f64::from(r1[x0 + 1]) * fx;
            sum += top * (1.0 - fy) + bottom * fy;
        }
    }
    Some(sum / f64::from((2 * k + 1) * (2 * k + 1)))
}

/// [`square_mean`] sample by sample, each checked against the image's bounds.
fn square_mean_checked(img: &GrayView<'_>, [cx, cy]: [f64; 2], step: f64, k: i32) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0u32;
    for j in -k..=k {
        for i in -k..=k {
            if let Some(v) = bilinear(img, cx + f64::from(i) * step, cy + f64::from(j) * step) {
                sum += v;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / f64::from(n))
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_unstable_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Reads the data bits of the quad `corners` (taken as NW, NE, SE, SW of the grid) with
/// reference levels, without dictionary lookup. Checks the corners, the contrast and the
/// border, as [`decode`] does.
pub fn read_cells(
    image: &GrayView<'_>,
    corners: &Corners,
    family: MarkerFamily,
    params: &DecodeParams,
) -> Result<CellReading, Rejection> {
    read_cells_with(image, corners, family, WhiteReference::QuietZone, params)
}

/// Where the white reference level of a reading comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WhiteReference {
    /// The median of the ring of quiet-zone cells just outside the border (the paper's
    /// markers, printed inside a white margin).
    QuietZone,
    /// The marker's own light cells: the border and data levels are split in two by Otsu's
    /// criterion and the white reference is the median of the data cells above the split.
    /// For markers that may be printed without a white margin (ArUco, AprilTag).
    DataCells,
}

impl WhiteReference {
    /// The reference a dictionary's markers are read with ([`Dictionary::uses_quiet_zone`]).
    pub fn of(dictionary: &Dictionary) -> Self {
        if dictionary.uses_quiet_zone() {
            Self::QuietZone
        } else {
            Self::DataCells
        }
    }
}

/// Otsu's split of sorted `values`: the index `i` (1..len) maximising the between-class
/// variance of `values[..i]` and `values[i..]`.
fn otsu_split(values: &[f64]) -> usize {
    let n = values.len();
    let total: f64 = values.iter().sum();
    let mut below = 0.0;
    let (mut best, mut best_i) = (-1.0, n);
    for i in 1..n {
        below += values[i - 1];
        let (w0, w1) = (i as f64, (n - i) as f64);
        let d = below / w0 - (total - below) / w1;
        let between = w0 * w1 * d * d;
        if between > best {
            best = between;
            best_i = i;
        }
    }
    best_i
}

/// [`read_cells`] with the white reference taken from `white` (the quiet zone is not read
/// at all with [`WhiteReference::DataCells`]).
pub fn read_cells_with(
    image: &GrayView<'_>,
    corners: &Corners,
    family: MarkerFamily,
    white_reference: WhiteReference,
    params: &DecodeParams,
) -> Result<CellReading, Rejection> {
    if !(params.sample_radius >= 0.0 && params.sample_radius <= 0.5) {
        return Err(Rejection::BadParams {
            reason: "sample_radius must be in [0, 0.5]",
        });
    }
    if !params.min_contrast.is_finite() {
        return Err(Rejection::BadParams {
            reason: "min_contrast must be finite",
        });
    }
    let area2 = convex_quad_area2(corners).map_err(|e| match e {
        crate::FiducialError::BadQuad { reason } => Rejection::BadQuad { reason },
        _ => Rejection::BadQuad {
            reason: "invalid corners",
        },
    })?;
    if area2 < 0.0 {
        return Err(Rejection::CounterClockwise);
    }
    let frame = CrossRatioFrame::new(corners).map_err(|_| Rejection::BadQuad {
        reason: "degenerate geometry in the cross-ratio construction",
    })?;
    let wc = family.width_cells() as i32;
    let hc = family.height_cells() as i32;
    let side = |i: usize, j: usize| (corners[j] - corners[i]).norm();
    let pitch = (side(0, 1).min(side(3, 2)) / f64::from(wc))
        .min(side(0, 3).min(side(1, 2)) / f64::from(hc));
    let radius = params.sample_radius * pitch;
    let sampler = Sampler {
        image,
        frame,
        width: f64::from(wc),
        height: f64::from(hc),
        radius,
        steps: (radius.floor() as i32).clamp(if radius > 0.25 { 1 } else { 0 }, MAX_STEPS),
    };

    // Border ring: black reference.
    let mut border = [0.0f64; MAX_BORDER];
    let mut nb = 0;
    for y in 0..hc {
        for x in 0..wc {
            if x == 0 || y == 0 || x == wc - 1 || y == hc - 1 {
                border[nb] = sampler.cell(x, y).ok_or(Rejection::OutsideImage)?;
                nb += 1;
            }
        }
    }
    // Quiet-zone ring: white reference (cells outside the image are skipped).
    let mut quiet = [0.0f64; MAX_QUIET];
    let mut nq = 0;
    if white_reference == WhiteReference::QuietZone {
        for y in -1..=hc {
            for x in -1..=wc {
                let ring = x == -1 || y == -1 || x == wc || y == hc;
                if let Some(v) = ring.then(|| sampler.cell(x, y)).flatten() {
                    quiet[nq] = v;
                    nq += 1;
                }
            }
        }
        if nq == 0 {
            return Err(Rejection::QuietZoneOutside);
        }
    }
    // Data cells, read before sorting the border (the median reorders it).
    let mut data = [0.0f64; 64];
    let (m, n) = (family.rows() as i32, family.cols() as i32);
    for r in 0..m {
        for c in 0..n {
            data[(r * n + c) as usize] =
                sampler.cell(c + 1, r + 1).ok_or(Rejection::OutsideImage)?;
        }
    }
    let cells = (m * n) as usize;
    reading_from_levels(
        &mut border[..nb],
        &mut quiet[..nq],
        &data,
        cells,
        white_reference,
        params,
    )
}

/// The reading of sampled cell levels: `border` (black reference), `quiet` (the white
/// reference with [`WhiteReference::QuietZone`]) and the first `cells` of `data`, checked
/// for contrast and a dark border as [`read_cells_with`] does. `border` and `quiet` are
/// reordered.
pub(crate) fn reading_from_levels(
    border: &mut [f64],
    quiet: &mut [f64],
    data: &[f64; 64],
    cells: usize,
    white_reference: WhiteReference,
    params: &DecodeParams,
) -> Result<CellReading, Rejection> {
    let nb = border.len();
    let white = match white_reference {
        WhiteReference::QuietZone => median(quiet),
        WhiteReference::DataCells => {
            let mut all = [0.0f64; MAX_BORDER + 64];
            all[..nb].copy_from_slice(border);
            all[nb..nb + cells].copy_from_slice(&data[..cells]);
            let all = &mut all[..nb + cells];
            all.sort_unstable_by(f64::total_cmp);
            let i = otsu_split(all);
            let split = if i < all.len() {
                0.5 * (all[i - 1] + all[i])
            } else {
                f64::INFINITY
            };
            // The light data cells, gathered into the (no longer needed) quiet buffer.
            let mut light = [0.0f64; 64];
            let mut nl = 0;
            for &v in data[..cells].iter().filter(|&&v| v > split) {
                light[nl] = v;
                nl += 1;
            }
            if nl == 0 {
                f64::NAN
            } else {
                median(&mut light[..nl])
            }
        }
    };
    let black = median(border);
    let contrast = white - black;
    if contrast.is_nan() || contrast < params.min_contrast.max(f64::MIN_POSITIVE) {
        return Err(Rejection::LowContrast {
            contrast,
            min: params.min_contrast,
        });
    }
    let threshold = 0.5 * (black + white);
    let light = border.iter().filter(|&&v| v > threshold).count() as u32;
    if light > params.max_light_border_cells {
        return Err(Rejection::BorderNotDark {
            light,
            max: params.max_light_border_cells,
        });
    }
    let mut code = 0u64;
    let mut margin = f64::INFINITY;
    let half = 0.5 * contrast;
    let mut scores = [0.0f64; 64];
    for (k, &v) in data.iter().take(cells).enumerate() {
        if v < threshold {
            code |= 1 << k;
        }
        let d = (v - threshold).abs();
        margin = margin.min(d);
        scores[k] = (d / half).min(1.0);
    }
    // The fit leaves out the `soft_errors` least clean cells: the soft decision tolerates
    // that many weak cells, so the choice of aspect must too (two weak cells of the right
    // grid otherwise let a grid read across the wrong aspect win).
    let scores = &mut scores[..cells.min(64)];
    scores.sort_unstable_by(f64::total_cmp);
    let drop = (params.soft_errors as usize)
        .min(MAX_SOFT)
        .min(scores.len().saturating_sub(1));
    let kept = &scores[drop..];
    let fit = kept.iter().sum::<f64>() / kept.len().max(1) as f64;
    Ok(CellReading {
        code,
        black,
        white,
        light_border_cells: light,
        confidence: (margin / half).min(1.0),
        fit,
        levels: *data,
    })
}

/// Reads the marker whose black border's outer corners are `corners` (clockwise in the
/// image, starting at any corner; pixel-centre coordinates, sub-pixel) and looks its code
/// up in `dictionary`.
///
/// Returns the entry, the bit errors corrected, the rotation and the corners re-ordered
/// into the marker's own NW, NE, SE, SW, or why the quad is not a marker.
pub fn decode(
    image: &GrayView<'_>,
    corners: &Corners,
    dictionary: &Dictionary,
    params: &DecodeParams,
) -> Result<Decoded, Rejection> {
    let (s, reading) = read_oriented(
        image,
        corners,
        dictionary.family(),
        WhiteReference::of(dictionary),
        params,
    )?;
    match_reading(corners, s, &reading, dictionary, params).ok_or_else(|| Rejection::NoMatch {
        read: reading.code,
        nearest: dictionary.nearest(reading.code).distance,
        max: params.max_errors.min(dictionary.max_correctable()),
    })
}

/// Reads the grid of `family` in the corner order that fits it (see the module docs): the
/// corner shift used and the reading.
pub(crate) fn read_oriented(
    image: &GrayView<'_>,
    corners: &Corners,
    family: MarkerFamily,
    white: WhiteReference,
    params: &DecodeParams,
) -> Result<(u8, CellReading), Rejection> {
    // Corner shifts to read: the grid maps onto itself under all quarter turns for a
    // square family (lookup covers them), under half turns otherwise (so also read with
    // the corners shifted by one).
    let shifts: &[u8] = if family.is_square() { &[0] } else { &[0, 1] };
    // Of the readings that pass the border and contrast checks, keep the one whose samples
    // fall most cleanly inside cells (the right aspect); only that one is looked up, so a
    // code read across the grid can never stand in for a rejected right reading.
    let mut chosen: Option<(u8, CellReading)> = None;
    let mut first_rejection = None;
    for &s in shifts {
        let frame_corners: Corners = core::array::from_fn(|i| corners[(i + s as usize) % 4]);
        match read_cells_with(image, &frame_corners, family, white, params) {
            Ok(r) => {
                if chosen.as_ref().is_none_or(|(_, c)| r.fit > c.fit) {
                    chosen = Some((s, r));
                }
            }
            Err(e) => {
                first_rejection.get_or_insert(e);
            }
        }
    }
    chosen.ok_or(first_rejection.unwrap_or(Rejection::BadQuad {
        reason: "no reading",
    }))
}

/// Looks a reading (taken with the corners shifted by `s`) up in `dictionary`, with hard
/// then soft correction; the decoded marker (dictionary 0) or `None`.
pub(crate) fn match_reading(
    corners: &Corners,
    s: u8,
    reading: &CellReading,
    dictionary: &Dictionary,
    params: &DecodeParams,
) -> Option<Decoded> {
    let max = params.max_errors.min(dictionary.max_correctable());
    let m = dictionary
        .lookup_within(reading.code, max)
        .or_else(|| soft_lookup(reading, dictionary, params))?;
    Some(decoded_from_match(corners, s, reading, &m))
}

/// The decoded marker (dictionary 0) of the entry `m` matched to `reading`, a reading taken
/// with the corners shifted by `s`.
pub(crate) fn decoded_from_match(
    corners: &Corners,
    s: u8,
    reading: &CellReading,
    m: &crate::dictionary::Match,
) -> Decoded {
    let rotation = (s + m.rotation) % 4;
    Decoded {
        dictionary: 0,
        index: m.index,
        code: m.code,
        distance: m.distance,
        rotation,
        corners: core::array::from_fn(|i| corners[(i + rotation as usize) % 4]),
        contrast: reading.contrast(),
        confidence: reading.confidence,
    }
}

/// Most cells considered by the soft decision (the dictionary's correction radius is lower
/// for any useful dictionary: 2 for the paper's).
const MAX_SOFT: usize = 4;

/// Soft-decision (erasure-style) lookup: flips subsets of the reading's weakest cells, those
/// among its `soft_errors` least confident whose margin is below `soft_margin`, and accepts
/// an entry matched *exactly* by the fewest flips. An entry that disagrees with the reading
/// in any confident cell is never accepted, however close it is in Hamming distance.
fn soft_lookup(
    reading: &CellReading,
    dictionary: &Dictionary,
    params: &DecodeParams,
) -> Option<crate::dictionary::Match> {
    let k = (params.soft_errors.min(dictionary.max_correctable()) as usize).min(MAX_SOFT);
    if k == 0 || params.soft_margin.is_nan() || params.soft_margin <= 0.0 {
        return None;
    }
    let cells = dictionary.family().bits() as usize;
    let (weak, n) = reading.weakest::<MAX_SOFT>(cells);
    let weak = &weak[..n.min(k)];
    let usable = weak
        .iter()
        .take_while(|(_, m)| *m < params.soft_margin)
        .count();
    let mut best: Option<crate::dictionary::Match> = None;
    for subset in 1u32..(1 << usable) {
        let flips = subset.count_ones();
        if best.is_some_and(|b| b.distance <= flips) {
            continue;
        }
        let mask = weak[..usable]
            .iter()
            .enumerate()
            .filter(|(i, _)| subset & (1 << i) != 0)
            .fold(0u64, |acc, (_, (cell, _))| acc | (1u64 << cell));
        if let Some(m) = dictionary.lookup_within(reading.code ^ mask, 0) {
            best = Some(crate::dictionary::Match {
                distance: flips,
                ..m
            });
        }
    }
    best
}

/// How much lighter than its border the inside of the quad `corners` (clockwise in the
/// image, from any corner) gets at its lightest, as a share of the step from the border to
/// the ring just outside it: the lightest of the centres of the cells inside a grid of
/// `cells` across, less the median of its border cells' centres, over the median of the
/// centres of the ring of cells around it less the same. `None` when the ring is not
/// lighter than the border by `min_step` grey levels or the quad cannot be sampled.
pub(crate) fn inside_lift(
    image: &GrayView<'_>,
    corners: &Corners,
    cells: f64,
    min_step: f64,
) -> Option<f64> {
    let frame = CrossRatioFrame::new(corners).ok()?;
    let n = cells.round().clamp(3.0, 12.0) as i32;
    let nf = f64::from(n);
    let at = |x: i32, y: i32| {
        let (a, b) = CrossRatioFrame::cell_coords(f64::from(x), f64::from(y), nf, nf);
        let p = frame.map(a, b)?;
        bilinear(image, p.x, p.y)
    };
    let mut border = [0.0f64; 4 * 12];
    let mut ring = [0.0f64; 4 * 14];
    let (mut nb, mut nr) = (0, 0);
    let mut lightest = f64::NEG_INFINITY;
    for y in -1..=n {
        for x in -1..=n {
            let outer = x == -1 || y == -1 || x == n || y == n;
            let edge = x == 0 || y == 0 || x == n - 1 || y == n - 1;
            if outer {
                if let Some(v) = at(x, y) {
                    ring[nr] = v;
                    nr += 1;
                }
            } else if edge {
                border[nb] = at(x, y)?;
                nb += 1;
            } else {
                lightest = lightest.max(at(x, y)?);
            }
        }
    }
    if nr == 0 {
        return None;
    }
    let dark = median(&mut border[..nb]);
    let step = median(&mut ring[..nr]) - dark;
    (step >= min_step).then(|| (lightest - dark) / step)
}

/// Most [`inside_lift`] of a quad that cannot be a marker, checked on its coarse corners
/// before the refinement ([`flat_inside`]). Every dictionary entry has light data cells,
/// and blur only spreads them: on the motion-blur rows (`cargo xtask detector-accuracy
/// --motion-blur`, seeds 81,000-81,019 and 83,000-83,039, 3-13 px) a bound of 0.3 read
/// the same markers, 0.5 lost one in 160 at 13 px. The squares of the chessboard photos
/// (`left01.jpg`, `left05.jpg`), which the first cut and the re-cut find by the dozen,
/// reach 0.04 at most; their refinement and reading took over a third of those frames.
const FLAT_INSIDE: f64 = 0.2;

/// Whether the inside of the quad `coarse` (corners clockwise in the image) is as dark as
/// its border, which no marker's is: its [`inside_lift`] on a grid of `cells` across is
/// under [`FLAT_INSIDE`] while the ring around it is lighter than the border by at least
/// the decoder's default contrast. A quad that cannot be sampled is not called flat.
pub(crate) fn flat_inside(image: &GrayView<'_>, coarse: &Corners, cells: f64) -> bool {
    let min_step = DecodeParams::default().min_contrast;
    inside_lift(image, coarse, cells, min_step).is_some_and(|l| l < FLAT_INSIDE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark square with light squares on its sides and dark ones at its corners, as on
    /// a chessboard (`left01.jpg`, `left05.jpg`), is flat inside; every entry of every
    /// standard dictionary, sharp or smeared by 1.5 cells of horizontal motion, is not.
    #[test]
    fn flat_inside_tells_chessboard_squares_from_markers() {
        let (cell, n) = (12usize, 5usize);
        let px: Vec<u8> = (0..(n * cell).pow(2))
            .map(|i| {
                let (x, y) = (i % (n * cell) / cell, i / (n * cell) / cell);
                if (x + y) % 2 == 0 { 30 } else { 220 }
            })
            .collect();
        let img = GrayView::new(&px, n * cell, n * cell).unwrap();
        // The centre square, (2, 2), on pixel centres of its outermost pixels.
        let (a, b) = (2.0 * cell as f64, 3.0 * cell as f64 - 1.0);
        let square = [
            nalgebra::Point2::new(a, a),
            nalgebra::Point2::new(b, a),
            nalgebra::Point2::new(b, b),
            nalgebra::Point2::new(a, b),
        ];
        for cells in [6.0, 8.0, 10.0] {
            assert!(flat_inside(&img, &square, cells), "{cells} cells");
        }
        let mut checked = 0;
        let names = crate::standard_dictionaries().iter().map(|d| d.name);
        for name in names.chain([crate::PAPER_NAME]) {
            let dict = crate::dictionary_by_name(name).unwrap();
            let family = dict.family();
            let cells = f64::from(family.width_cells().max(family.height_cells()));
            let options = crate::RenderOptions {
                px_per_cell: 4,
                quiet_cells: 2,
            };
            for &code in dict.codes() {
                let m = crate::render_marker(family, code, &options).unwrap();
                let (w, h) = (m.width(), m.height());
                // A box blur of 6 px along x.
                let smeared = marker_testkit::motion_blur(m.pixels(), w, h, 6.0, 0.0).unwrap();
                for px in [m.pixels(), &smeared[..]] {
                    let img = GrayView::new(px, w, h).unwrap();
                    let lift = inside_lift(&img, &m.corners(), cells, 20.0);
                    assert!(
                        lift.is_some_and(|l| l > 2.0 * FLAT_INSIDE),
                        "{name}: code {code:#x} lifts {lift:?}"
                    );
                    assert!(!flat_inside(&img, &m.corners(), cells));
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000, "{checked} markers");
    }

    proptest::proptest! {
        /// The sampler's fast path (every sample inside, rows and columns shared) gives
        /// the bits of the sample-by-sample reading.
        #[test]
        fn square_mean_matches_the_checked_samples(
            w in 2usize..30,
            h in 2usize..30,
            seed in proptest::prelude::any::<u64>(),
            cx in -3.0f64..33.0,
            cy in -3.0f64..33.0,
            step in 0.0f64..2.5,
            k in 0i32..=MAX_STEPS,
        ) {
            let px = crate::test_bytes(seed, w * h, |_, state| {
                state as u8
            });
            let img = GrayView::new(&px, w, h).unwrap();
            let fast = square_mean(&img, [cx, cy], step, k);
            let checked = square_mean_checked(&img, [cx, cy], step, k);
            proptest::prop_assert_eq!(fast.map(f64::to_bits), checked.map(f64::to_bits));
        }
    }
}
