//! The per-component stages that serial and banded-parallel detection share: what one scan
//! needs to examine a component (trace, fit, refine), what decoding a quad needs, and the
//! merge of readings. `detector` runs them on the calling thread, `parallel` on rayon's
//! threads; neither module imports the other's internals, both import these.

use crate::contour::{Component, trace_outer};
use crate::decode::{
    CellReading, Decoded, Rejection, WhiteReference, match_reading, read_oriented,
};
use crate::dictionary::Dictionary;
use crate::image::{Corners, GrayView};
use crate::quad::{QuadLimits, fit_quad};
use crate::refine::Refiner;
use crate::sides::side_offsets;
use crate::split::Rect;

use crate::config::DetectorConfig;

/// A candidate marker outline with sub-pixel corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quad {
    /// Corners in pixel-centre coordinates, clockwise in the image (v down). Which corner is
    /// the marker's north-west is only known after decoding.
    pub corners: Corners,
    /// Mean grey-level step across the four edges (0-255): a confidence measure.
    pub contrast: f64,
    /// Whether the second look's re-cut found it (its outline closed at a quarter of the
    /// local range, [`crate::split`]): such a quad is not read as motion-blurred (see
    /// [`DecodeContext::decode`]).
    pub(crate) dark_cut: bool,
}

/// What one scan of a detection needs to examine a component.
pub(crate) struct Scan<'a, 'i> {
    pub(crate) img: &'a GrayView<'i>,
    pub(crate) bin: &'a [u8],
    pub(crate) w: usize,
    pub(crate) h: usize,
    pub(crate) limits: &'a QuadLimits,
    pub(crate) margin: u32,
    pub(crate) min_side: u32,
    pub(crate) factor: usize,
    pub(crate) config: &'a DetectorConfig,
    pub(crate) cells_across: f64,
}

/// The fate of one component.
pub(crate) enum Examined {
    /// A refined quad.
    Quad(Quad),
    /// No quad: its box goes to the re-cut ([`Splitter`]).
    Retry(Rect),
    /// Rejected outright.
    Dropped,
}

impl Scan<'_, '_> {
    /// Whether `c` is too small to hold a marker: [`Scan::examine`] drops it first thing.
    pub(crate) fn too_small(&self, c: &Component) -> bool {
        let bw = c.x_max - c.x_min + 1;
        let bh = c.y_max - c.y_min + 1;
        bw.max(bh) < self.min_side || bw.min(bh) < self.min_side / 2
    }

    /// Cheap rejections, tracing, quad fit and refinement of one component.
    pub(crate) fn examine(
        &self,
        c: &Component,
        contour: &mut Vec<[i32; 2]>,
        refiner: &mut Refiner,
    ) -> Examined {
        let (w, h, m) = (self.w, self.h, self.margin);
        let cfg = self.config;
        let bw = c.x_max - c.x_min + 1;
        let bh = c.y_max - c.y_min + 1;
        // Cheap rejections first: size, frame border, sparsity.
        if self.too_small(c) {
            return Examined::Dropped;
        }
        let rect = Rect {
            x0: c.x_min,
            y0: c.y_min,
            x1: c.x_max,
            y1: c.y_max,
        };
        if c.pixels < bw.max(bh) + bw.min(bh)
            || c.x_min < m
            || c.y_min < m
            || c.x_max as usize + m as usize >= w
            || c.y_max as usize + m as usize >= h
        {
            return Examined::Retry(rect);
        }
        let max_len = 2 * (bw + bh) as usize + 16;
        if !trace_outer(self.bin, w, c.start_x, c.y_min, max_len, contour) {
            return Examined::Retry(rect);
        }
        let Some(mut coarse) = fit_quad(contour, self.limits) else {
            return Examined::Retry(rect);
        };
        if self.factor > 1 {
            // Small pixel i covers full pixels f i .. f i + f - 1: its centre is at
            // f i + (f - 1) / 2 in full-resolution pixel-centre coordinates.
            let scale = self.factor as f64;
            let off = 0.5 * (scale - 1.0);
            for c in &mut coarse {
                c.x = c.x * scale + off;
                c.y = c.y * scale + off;
            }
        }
        match refine_candidate(
            self.img,
            &coarse,
            refiner,
            cfg,
            cfg.min_angle_deg,
            self.cells_across,
        ) {
            Some((corners, contrast)) => Examined::Quad(Quad {
                corners,
                contrast,
                dark_cut: false,
            }),
            None => Examined::Dropped,
        }
    }
}

/// The refined corners of the candidate `coarse` and their contrast, as the first pass
/// and the second look both take them: `None` when its inside is as dark as its border
/// ([`crate::decode::flat_inside`], checked on the coarse corners first: no marker's is)
/// or when the refinement cannot fit its sides.
pub(crate) fn refine_candidate(
    img: &GrayView<'_>,
    coarse: &Corners,
    refiner: &mut Refiner,
    cfg: &DetectorConfig,
    min_angle_deg: f64,
    cells_across: f64,
) -> Option<(Corners, f64)> {
    if crate::decode::flat_inside(img, coarse, cells_across) {
        return None;
    }
    refiner.refine(img, coarse, &cfg.refine, min_angle_deg, cells_across)
}

/// Scratch of decoding one quad at a time, owned by the detector (one per thread in
/// a parallel search).
#[derive(Debug, Clone)]
pub(crate) struct Decoding {
    /// Per dictionary, the reading of the current quad (valid where `grid_of[i] == i`).
    readings: Vec<Option<(u8, CellReading)>>,
    pattern: crate::pattern::PatternRefiner,
    photometric: crate::photometric::PhotometricFit,
    /// Scratch of the motion-blurred reading ([`DetectorConfig::motion_blur`]).
    pub(crate) blur: crate::blur::BlurScratch,
}

impl Decoding {
    /// Scratch for `dictionaries` dictionaries.
    pub(crate) fn new(dictionaries: usize) -> Self {
        Self {
            readings: vec![None; dictionaries],
            pattern: crate::pattern::PatternRefiner::default(),
            photometric: crate::photometric::PhotometricFit::default(),
            blur: crate::blur::BlurScratch::default(),
        }
    }
}

/// What decoding a quad reads from the detector (shared by its threads).
pub(crate) struct DecodeContext<'a> {
    pub(crate) config: &'a DetectorConfig,
    pub(crate) dictionaries: &'a [Dictionary],
    pub(crate) grid_of: &'a [usize],
}

impl DecodeContext<'_> {
    /// The number of dictionaries.
    pub(crate) fn dictionaries(&self) -> usize {
        self.dictionaries.len()
    }

    /// Reads quad `q` of `img`: the decoded marker with its corners refined against its
    /// pattern, or `None` when it is not a marker (or a side of it runs along an occluder).
    pub(crate) fn decode(
        &self,
        img: &GrayView<'_>,
        q: &Quad,
        scratch: &mut Decoding,
    ) -> Option<Decoded> {
        let params = &self.config.decode;
        let mut best: Option<Decoded> = None;
        // Whether some grid read as a marker's (contrast, and a dark border or nearly):
        // only such a quad is worth the motion-blurred reading.
        let mut marker_like = false;
        for (i, dict) in self.dictionaries.iter().enumerate() {
            let g = self.grid_of[i];
            if g == i {
                let r = read_oriented(
                    img,
                    &q.corners,
                    dict.family(),
                    WhiteReference::of(dict),
                    params,
                );
                marker_like |= matches!(r, Ok(_) | Err(Rejection::BorderNotDark { .. }));
                scratch.readings[i] = r.ok();
            }
            let Some((s, reading)) = &scratch.readings[g] else {
                continue;
            };
            if let Some(mut d) = match_reading(&q.corners, *s, reading, dict, params)
                && best.is_none_or(|b| d.distance < b.distance)
            {
                d.dictionary = i;
                best = Some(d);
            }
        }
        // Not an entry as sampled: read it as a motion-blurred marker (issue #16), unless
        // the re-cut found it. The re-cut closes outlines that stay dark below a quarter of
        // the local range, and a marker smeared by the 1.5 cells or more the blurred
        // reading models has none: wherever a white cell adjoins its border across the
        // motion, the smear averages the one black cell with at least half a cell of white
        // on every pixel, a third of the contrast above black or more, so the outline is
        // open there at that cut. (A marker far dimmer than its neighbourhood could still
        // close; on the motion-blur rows of `cargo xtask detector-accuracy --motion-blur`
        // and the sets of `cargo xtask motion-sets` no marker was read this way, while
        // board.jpg's two blurred readings and the clutter bench frame's one, about 0.8 ms
        // of each frame, were of the re-cut's quads.)
        // Read as sampled, the marker is sharp enough for the photometric step's model.
        let sharp = best.is_some();
        let best = best.or_else(|| {
            (self.config.motion_blur && marker_like && !q.dark_cut)
                .then(|| {
                    crate::blur::decode_blurred(
                        img,
                        &q.corners,
                        self.dictionaries,
                        params,
                        &mut scratch.blur,
                    )
                })
                .flatten()
        });
        let mut d = best?;
        let family = self.dictionaries[d.dictionary].family();
        // The corners against the decoded pattern (issue #13), then, on markers with small
        // cells read as sampled, fitted to the whole modelled marker (issue #30). That
        // model's blur is a round Gaussian; a marker that needed the motion-blurred reading
        // is smeared along a line it does not describe (at 3 px of motion its corners came
        // out 0.046 px RMS off with the fit, 0.042 without). Each step keeps the corners
        // before it where its model does not fit.
        let cfg = &self.config.refine;
        let cells = (cfg.with_pattern || cfg.photometric_below_px > 0.0)
            .then(|| crate::pattern::Cells::new(family, d.code))
            .flatten();
        let mut refined = None;
        if let Some(cells) = &cells {
            if cfg.with_pattern {
                refined = scratch.pattern.refine(img, &d.corners, cells, cfg);
            }
            let start = refined.unwrap_or(d.corners);
            let (cw, ch) = cells.cell_px(&start);
            let cell = cw.min(ch);
            if sharp && cell < cfg.photometric_below_px {
                refined = scratch
                    .photometric
                    .fit(img, &start, cells, 1.0, cell)
                    .or(refined);
            }
        }
        // A side along an occluder, not the border (issue #16). On a narrow border under a
        // wider blur than the side check allows for (a tag seen obliquely in a real photo,
        // cells of 2-3 px), the plain corners can put the grid a few tenths of a pixel off,
        // which reads as a border too thin; the pattern step's corners, fitted to every
        // cell, put it right. So a marker is dropped only when the check fails on both.
        if let Some(check) = &self.config.side_check {
            let fails = |corners: &Corners| {
                let mut e = d;
                e.corners = *corners;
                side_offsets(img, &e, family, check).is_some_and(|o| !o.consistent())
            };
            if fails(&d.corners) && refined.as_ref().is_none_or(fails) {
                return None;
            }
        }
        if let Some(c) = refined {
            d.corners = c;
        }
        Some(d)
    }
}

/// Adds `d` to `out` unless a reading of the same marker is there (then the better of the
/// two is kept: fewer bit errors, then higher contrast).
pub(crate) fn push_unique(out: &mut Vec<Decoded>, d: Decoded) {
    match out
        .iter_mut()
        .find(|o| o.dictionary == d.dictionary && o.index == d.index && overlaps(o, &d))
    {
        Some(o) => {
            if (d.distance, -d.contrast) < (o.distance, -o.contrast) {
                *o = d;
            }
        }
        None => out.push(d),
    }
}

/// Two readings of one marker: their centres are within half a side of each other.
fn overlaps(a: &Decoded, b: &Decoded) -> bool {
    let ca = a
        .corners
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p.x / 4.0, s[1] + p.y / 4.0]);
    let cb = b
        .corners
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p.x / 4.0, s[1] + p.y / 4.0]);
    let side = (a.corners[1] - a.corners[0]).norm();
    (ca[0] - cb[0]).hypot(ca[1] - cb[1]) < 0.5 * side
}
