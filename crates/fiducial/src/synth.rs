//! Synthetic test scenes with exact ground truth: the generator behind the detector's
//! property tests, accuracy tables (`cargo xtask detector-accuracy`) and benchmarks.
//!
//! A scene is rendered physically in floating point and quantised once at the end:
//! reflectance (markers warped by a homography onto a background) times a lighting ramp, then
//! an optical Gaussian blur, then Gaussian sensor noise. Warping samples the texture
//! analytically: each pixel is probed at its corners, edge midpoints and centre, and a pixel
//! whose probes disagree (it straddles an edge) is resampled with 12x12 samples, one per cell
//! of a 12x12 grid and each in its own column and row of a 144x144 grid (so even an edge
//! along a pixel axis is placed to 1/288 px), and the ground-truth corners (the homography
//! applied to the marker's corners) are exact in the pixel-centre convention of spec 2.1. All randomness comes from the caller's seeded RNG.

use nalgebra::{Matrix3, Point2, Vector3};
use rand::{Rng, RngExt};
use rand_distr::{Distribution, StandardNormal};
use thiserror::Error;

use crate::dictionary::Dictionary;
use crate::family::MarkerFamily;
use crate::image::Corners;

/// Why a scene cannot be generated.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SynthError {
    /// The frame is empty or larger than the detector accepts.
    #[error("scene size {width}x{height} is not usable (1..=16384 per side)")]
    BadSize {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
    /// The marker size range is empty or not positive.
    #[error("marker sides {min}..{max} px are not a valid range")]
    BadSides {
        /// Smallest side.
        min: f64,
        /// Largest side.
        max: f64,
    },
    /// The markers did not fit without overlapping.
    #[error(
        "could only place {placed} of {wanted} markers without overlap; use fewer or smaller markers"
    )]
    NoRoom {
        /// Markers placed.
        placed: usize,
        /// Markers asked for.
        wanted: usize,
    },
}

/// A rectangle of black and white cells (the whole marker, border included), drawn on the
/// unit square, with a white quiet zone around it.
#[derive(Debug, Clone, PartialEq)]
pub struct CellPattern {
    /// Cells across.
    pub cols: usize,
    /// Cells down.
    pub rows: usize,
    /// Row-major, `true` = black.
    pub cells: Vec<bool>,
    /// Width of the white quiet zone, in cells.
    pub quiet_cells: f64,
}

impl CellPattern {
    /// A marker-like pattern: a one-cell black border around `data_rows x data_cols` random
    /// cells, with a one-cell quiet zone.
    pub fn random_marker<R: Rng + ?Sized>(data_rows: usize, data_cols: usize, rng: &mut R) -> Self {
        let bits: Vec<bool> = (0..data_rows * data_cols)
            .map(|_| rng.random_bool(0.5))
            .collect();
        Self::from_bits(data_rows, data_cols, &bits)
    }

    /// A marker with the given data bits (`bits[k]`, `k = row * data_cols + col`, true =
    /// black, as in spec 3.1) inside a one-cell black border and a one-cell quiet zone.
    pub fn from_bits(data_rows: usize, data_cols: usize, bits: &[bool]) -> Self {
        let (rows, cols) = (data_rows + 2, data_cols + 2);
        let cells = (0..rows * cols)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                if r == 0 || c == 0 || r == rows - 1 || c == cols - 1 {
                    true
                } else {
                    bits.get((r - 1) * data_cols + (c - 1))
                        .copied()
                        .unwrap_or(false)
                }
            })
            .collect();
        Self {
            cols,
            rows,
            cells,
            quiet_cells: 1.0,
        }
    }

    /// The real marker with `code` of `family` (bit `k = row * cols + col`, black = 1, spec
    /// 3.1) in a one-cell black border and a one-cell quiet zone: the same cells
    /// [`crate::render_marker`] draws, sampled analytically at any pose.
    pub fn from_code(family: MarkerFamily, code: u64) -> Self {
        let (rows, cols) = (family.rows() as usize, family.cols() as usize);
        let bits: Vec<bool> = (0..rows * cols).map(|k| (code >> k) & 1 == 1).collect();
        Self::from_bits(rows, cols, &bits)
    }

    /// Width over height of the pattern (cells are square when drawn at this aspect).
    pub fn aspect(&self) -> f64 {
        self.cols as f64 / self.rows.max(1) as f64
    }

    /// Reflectance at unit-square coordinates `(u, v)`: `Some(0.0)` black, `Some(1.0)`
    /// white (cells or quiet zone), `None` outside the quiet zone.
    fn sample(&self, u: f64, v: f64) -> Option<f32> {
        let x = u * self.cols as f64;
        let y = v * self.rows as f64;
        let q = self.quiet_cells;
        if x < -q || y < -q || x >= self.cols as f64 + q || y >= self.rows as f64 + q {
            return None;
        }
        if x < 0.0 || y < 0.0 || x >= self.cols as f64 || y >= self.rows as f64 {
            return Some(1.0);
        }
        let i = (y as usize) * self.cols + x as usize;
        Some(if self.cells.get(i).copied().unwrap_or(false) {
            0.0
        } else {
            1.0
        })
    }
}

/// The homography that maps the unit square's corners `(0,0), (1,0), (1,1), (0,1)` to
/// `corners` (in that order), or `None` if the quadrilateral is degenerate.
pub fn homography_from_unit_square(corners: &[[f64; 2]; 4]) -> Option<Matrix3<f64>> {
    let [[x0, y0], [x1, y1], [x2, y2], [x3, y3]] = *corners;
    let (dx1, dx2, dx3) = (x1 - x2, x3 - x2, x0 - x1 + x2 - x3);
    let (dy1, dy2, dy3) = (y1 - y2, y3 - y2, y0 - y1 + y2 - y3);
    let den = dx1 * dy2 - dx2 * dy1;
    if den.abs() < 1e-12 {
        return None;
    }
    let g = (dx3 * dy2 - dx2 * dy3) / den;
    let h = (dx1 * dy3 - dx3 * dy1) / den;
    let m = Matrix3::new(
        x1 - x0 + g * x1,
        x3 - x0 + h * x3,
        x0,
        y1 - y0 + g * y1,
        y3 - y0 + h * y3,
        y0,
        g,
        h,
        1.0,
    );
    m.iter().all(|v| v.is_finite()).then_some(m)
}

fn apply(h: &Matrix3<f64>, x: f64, y: f64) -> [f64; 2] {
    let p = h * Vector3::new(x, y, 1.0);
    [p.x / p.z, p.y / p.z]
}

/// A floating-point frame being rendered (reflectance or radiance, 0-255 scale).
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major values.
    pub data: Vec<f32>,
}

impl Canvas {
    /// A frame filled with `value`.
    pub fn new(width: usize, height: usize, value: f32) -> Result<Self, SynthError> {
        if width == 0 || height == 0 || width > 16_384 || height > 16_384 {
            return Err(SynthError::BadSize { width, height });
        }
        Ok(Self {
            width,
            height,
            data: vec![value; width * height],
        })
    }

    /// Draws `pattern` (white = `white`, black = `black`) warped onto the quadrilateral
    /// `corners` (images of the unit square's corners, the quiet zone extends beyond). Returns
    /// `false` (drawing nothing) if the quadrilateral is degenerate.
    pub fn draw_pattern(
        &mut self,
        pattern: &CellPattern,
        corners: &[[f64; 2]; 4],
        black: f32,
        white: f32,
    ) -> bool {
        let Some(h) = homography_from_unit_square(corners) else {
            return false;
        };
        let Some(inv) = h.try_inverse() else {
            return false;
        };
        // Bounding box of the quiet zone's image.
        let qu = pattern.quiet_cells / pattern.cols as f64;
        let qv = pattern.quiet_cells / pattern.rows as f64;
        let outer = [
            apply(&h, -qu, -qv),
            apply(&h, 1.0 + qu, -qv),
            apply(&h, 1.0 + qu, 1.0 + qv),
            apply(&h, -qu, 1.0 + qv),
        ];
        let xs = outer.iter().map(|p| p[0]);
        let ys = outer.iter().map(|p| p[1]);
        let x0 = xs.clone().fold(f64::MAX, f64::min).floor().max(0.0) as usize;
        let x1 = (xs.fold(f64::MIN, f64::max).ceil() + 1.0).clamp(0.0, self.width as f64) as usize;
        let y0 = ys.clone().fold(f64::MAX, f64::min).floor().max(0.0) as usize;
        let y1 = (ys.fold(f64::MIN, f64::max).ceil() + 1.0).clamp(0.0, self.height as f64) as usize;
        let value = |x: f64, y: f64| -> Option<f32> {
            let [u, v] = apply(&inv, x, y);
            pattern.sample(u, v).map(|r| black + r * (white - black))
        };
        for y in y0..y1 {
            for x in x0..x1 {
                let (fx, fy) = (x as f64, y as f64);
                // Probe the pixel's corners, edge midpoints and centre: a straight edge
                // through the pixel separates some of them.
                let mut probes = [None; 9];
                for (k, p) in probes.iter_mut().enumerate() {
                    let ox = (k % 3) as f64 * 0.5 - 0.5;
                    let oy = (k / 3) as f64 * 0.5 - 0.5;
                    *p = value(fx + ox, fy + oy);
                }
                let pix = &mut self.data[y * self.width + x];
                if probes.iter().all(|p| p.is_some() && *p == probes[0]) {
                    *pix = probes[0].unwrap_or(*pix);
                    continue;
                }
                if probes.iter().all(Option::is_none) && !near_quad(&outer, fx, fy) {
                    continue;
                }
                const S: usize = 12;
                let mut sum = 0.0f32;
                for j in 0..S {
                    for i in 0..S {
                        // One sample per cell of an S x S grid, each in its own column
                        // and row of an S^2 x S^2 grid, so that an edge along a pixel axis
                        // is seen at S^2 offsets rather than S.
                        let sx = fx - 0.5 + (i as f64 + (j as f64 + 0.5) / S as f64) / S as f64;
                        let sy = fy - 0.5 + (j as f64 + (i as f64 + 0.5) / S as f64) / S as f64;
                        sum += value(sx, sy).unwrap_or(*pix);
                    }
                }
                *pix = sum / (S * S) as f32;
            }
        }
        true
    }

    /// Multiplies by a horizontal lighting ramp: 1 at the left edge falling linearly to
    /// `1 / ratio` at the right edge (`ratio` 4 is a 4:1 gradient; 1 is uniform).
    pub fn light_gradient(&mut self, ratio: f64) {
        let ratio = if ratio.is_finite() && ratio >= 1.0 {
            ratio
        } else {
            1.0
        };
        let w = self.width;
        for row in self.data.chunks_exact_mut(w) {
            for (x, v) in row.iter_mut().enumerate() {
                let t = if w > 1 {
                    x as f64 / (w - 1) as f64
                } else {
                    0.0
                };
                *v *= (1.0 + t * (1.0 / ratio - 1.0)) as f32;
            }
        }
    }

    /// Separable Gaussian blur with standard deviation `sigma` pixels (borders replicated);
    /// `sigma <= 0` does nothing.
    pub fn blur(&mut self, sigma: f64) {
        if !sigma.is_finite() || sigma <= 0.0 {
            return;
        }
        let r = (3.0 * sigma).ceil() as isize;
        let mut k: Vec<f32> = (-r..=r)
            .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
            .collect();
        let s: f32 = k.iter().sum();
        k.iter_mut().for_each(|v| *v /= s);
        let (w, h) = (self.width as isize, self.height as isize);
        let mut tmp = vec![0.0f32; self.data.len()];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    let xx = (x + i as isize - r).clamp(0, w - 1);
                    acc += kv * self.data[(y * w + xx) as usize];
                }
                tmp[(y * w + x) as usize] = acc;
            }
        }
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    let yy = (y + i as isize - r).clamp(0, h - 1);
                    acc += kv * tmp[(yy * w + x) as usize];
                }
                self.data[(y * w + x) as usize] = acc;
            }
        }
    }

    /// Adds Gaussian noise of standard deviation `sigma` grey levels.
    pub fn noise<R: Rng + ?Sized>(&mut self, sigma: f64, rng: &mut R) {
        if !sigma.is_finite() || sigma <= 0.0 {
            return;
        }
        for v in &mut self.data {
            let n: f64 = StandardNormal.sample(rng);
            *v += (n * sigma) as f32;
        }
    }

    /// Rounds and clamps to 8-bit grey.
    pub fn to_gray(&self) -> Vec<u8> {
        self.data
            .iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect()
    }
}

fn near_quad(q: &[[f64; 2]; 4], x: f64, y: f64) -> bool {
    let xs = q.iter().map(|p| p[0]);
    let ys = q.iter().map(|p| p[1]);
    let (xmin, xmax) = (
        xs.clone().fold(f64::MAX, f64::min),
        xs.fold(f64::MIN, f64::max),
    );
    let (ymin, ymax) = (
        ys.clone().fold(f64::MAX, f64::min),
        ys.fold(f64::MIN, f64::max),
    );
    x >= xmin - 1.0 && x <= xmax + 1.0 && y >= ymin - 1.0 && y <= ymax + 1.0
}

/// Settings of a marker scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneConfig {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// Markers to place.
    pub markers: usize,
    /// Smallest marker side (the black border's outer edge), pixels.
    pub min_side: f64,
    /// Largest marker side, pixels.
    pub max_side: f64,
    /// Corner jitter as a fraction of the side (0 = rotated squares; 0.15 = strong
    /// perspective).
    pub perspective: f64,
    /// Optical blur sigma, pixels.
    pub blur: f64,
    /// Sensor noise sigma, grey levels.
    pub noise: f64,
    /// Lighting ratio across the frame (1 = uniform, 4 = 4:1).
    pub lighting: f64,
    /// Grey level of black cells (before lighting).
    pub black: f32,
    /// Grey level of white cells and background (before lighting).
    pub white: f32,
}

impl Default for SceneConfig {
    /// The accuracy scene: 640x480, 8 markers of 20-120 px, perspective 0.12, blur 1, noise 3,
    /// uniform light, black 30, white 220.
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            markers: 8,
            min_side: 20.0,
            max_side: 120.0,
            perspective: 0.12,
            blur: 1.0,
            noise: 3.0,
            lighting: 1.0,
            black: 30.0,
            white: 220.0,
        }
    }
}

/// One marker placed in a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedMarker {
    /// The drawn pattern.
    pub pattern: CellPattern,
    /// Its dictionary index, for real markers ([`marker_scene`]).
    pub index: Option<usize>,
    /// Exact image corners NW, NE, SE, SW of the black border's outer edge (pixel centres).
    pub corners: Corners,
}

/// A rendered scene: 8-bit grey pixels and ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major grey pixels.
    pub pixels: Vec<u8>,
    /// The markers drawn.
    pub markers: Vec<PlacedMarker>,
}

/// Random non-overlapping marker outlines for a frame: `cfg.markers` quadrilaterals whose
/// longer side is in `[min_side, max_side]` and whose width over height is `aspect`, with
/// random rotation and perspective jitter, each with room for a quiet zone of `quiet`
/// (fraction of the side) and a 3-pixel gap to the frame border.
pub fn random_placements<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    quiet: f64,
    aspect: f64,
    rng: &mut R,
) -> Result<Vec<[[f64; 2]; 4]>, SynthError> {
    let aspect = if aspect.is_finite() && aspect > 0.0 {
        aspect
    } else {
        1.0
    };
    let (sx, sy) = if aspect >= 1.0 {
        (1.0, 1.0 / aspect)
    } else {
        (aspect, 1.0)
    };
    if cfg.width == 0 || cfg.height == 0 || cfg.width > 16_384 || cfg.height > 16_384 {
        return Err(SynthError::BadSize {
            width: cfg.width,
            height: cfg.height,
        });
    }
    if !(cfg.min_side > 0.0 && cfg.min_side <= cfg.max_side && cfg.max_side.is_finite()) {
        return Err(SynthError::BadSides {
            min: cfg.min_side,
            max: cfg.max_side,
        });
    }
    let mut placed: Vec<([f64; 2], f64, [[f64; 2]; 4])> = Vec::new();
    let mut attempts = 0;
    while placed.len() < cfg.markers && attempts < 20_000 {
        attempts += 1;
        let side = rng.random_range(cfg.min_side..=cfg.max_side);
        let jitter = cfg.perspective.clamp(0.0, 0.3) * side;
        // Radius that holds the marker, its quiet zone and the jitter.
        let radius = (0.5 * side * (1.0 + 2.0 * quiet) + jitter) * std::f64::consts::SQRT_2 + 2.0;
        let (w, h) = (cfg.width as f64, cfg.height as f64);
        if 2.0 * radius + 6.0 > w.min(h) {
            continue;
        }
        let c = [
            rng.random_range(radius + 3.0..w - radius - 3.0),
            rng.random_range(radius + 3.0..h - radius - 3.0),
        ];
        if placed
            .iter()
            .any(|(p, r, _)| (p[0] - c[0]).hypot(p[1] - c[1]) < r + radius)
        {
            continue;
        }
        let theta = rng.random_range(0.0..std::f64::consts::TAU);
        let (s, co) = theta.sin_cos();
        let unit = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]];
        let corners = unit.map(|[u, v]| {
            let (x, y) = (u * side * sx, v * side * sy);
            [
                c[0] + co * x - s * y + rng.random_range(-jitter..=jitter),
                c[1] + s * x + co * y + rng.random_range(-jitter..=jitter),
            ]
        });
        if !crate::quad::convex_clockwise(&corners, 45.0) {
            continue;
        }
        placed.push((c, radius, corners));
    }
    if placed.len() < cfg.markers {
        return Err(SynthError::NoRoom {
            placed: placed.len(),
            wanted: cfg.markers,
        });
    }
    Ok(placed.into_iter().map(|(_, _, q)| q).collect())
}

/// Renders `patterns` (one per placement, cycled) onto a white frame at random placements,
/// then applies lighting, blur and noise as configured.
pub fn render_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    patterns: &[CellPattern],
    rng: &mut R,
) -> Result<Scene, SynthError> {
    render_indexed(cfg, patterns, &[], rng)
}

/// [`render_scene`] recording a dictionary index per pattern.
fn render_indexed<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    patterns: &[CellPattern],
    indices: &[usize],
    rng: &mut R,
) -> Result<Scene, SynthError> {
    let quiet = patterns
        .iter()
        .map(|p| p.quiet_cells / p.cols.min(p.rows).max(1) as f64)
        .fold(0.0, f64::max);
    let aspect = patterns.first().map_or(1.0, CellPattern::aspect);
    let places = random_placements(cfg, quiet, aspect, rng)?;
    let mut canvas = Canvas::new(cfg.width, cfg.height, cfg.white)?;
    let mut markers = Vec::with_capacity(places.len());
    for (i, q) in places.iter().enumerate() {
        let Some(pattern) = patterns.get(i % patterns.len().max(1)) else {
            break;
        };
        canvas.draw_pattern(pattern, q, cfg.black, cfg.white);
        markers.push(PlacedMarker {
            pattern: pattern.clone(),
            index: indices.get(i % indices.len().max(1)).copied(),
            corners: q.map(|[x, y]| Point2::new(x, y)),
        });
    }
    canvas.light_gradient(cfg.lighting);
    canvas.blur(cfg.blur);
    canvas.noise(cfg.noise, rng);
    Ok(Scene {
        width: cfg.width,
        height: cfg.height,
        pixels: canvas.to_gray(),
        markers,
    })
}

/// A scene of `cfg.markers` real markers: distinct random entries of `dictionary` drawn
/// with their true aspect (square cells). Each [`PlacedMarker`] records its index.
pub fn marker_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    dictionary: &Dictionary,
    rng: &mut R,
) -> Result<Scene, SynthError> {
    let n = cfg.markers.max(1);
    let mut indices: Vec<usize> = Vec::with_capacity(n);
    while indices.len() < n {
        let i = rng.random_range(0..dictionary.len().max(1));
        if !indices.contains(&i) || indices.len() >= dictionary.len() {
            indices.push(i);
        }
    }
    let patterns: Vec<CellPattern> = indices
        .iter()
        .map(|&i| CellPattern::from_code(dictionary.family(), dictionary.code(i).unwrap_or(0)))
        .collect();
    render_indexed(cfg, &patterns, &indices, rng)
}

/// A foreign marker: a one-cell black border around a random `rows x cols` code that is
/// *not* in `dictionary` (none of its entries in any orientation), with a one-cell quiet
/// zone. A detector reading it as a dictionary entry has corrected bit errors that were
/// never there; the rate of such reads is a property of the dictionary's distance and the
/// correction allowed.
pub fn foreign_marker<R: Rng + ?Sized>(dictionary: &Dictionary, rng: &mut R) -> CellPattern {
    let family = dictionary.family();
    loop {
        let code = rng.random_range(0..=family.mask());
        if dictionary.lookup_within(code, 0).is_none() {
            return CellPattern::from_code(family, code);
        }
    }
}

/// A scene of `cfg.markers` random marker-like patterns (`data_rows x data_cols` random cells
/// inside a black border): the stand-in for real markers in corner-accuracy tests.
pub fn random_marker_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    data_rows: usize,
    data_cols: usize,
    rng: &mut R,
) -> Result<Scene, SynthError> {
    let patterns: Vec<CellPattern> = (0..cfg.markers.max(1))
        .map(|_| CellPattern::random_marker(data_rows, data_cols, rng))
        .collect();
    render_scene(cfg, &patterns, rng)
}

/// A marker-free clutter frame: smooth textured noise, random rectangles (some of them
/// black-bordered squares with random insides of any grid size, the hardest impostors),
/// checker patches and short dark strokes like text, then
/// blur `blur` and noise `noise`.
pub fn clutter_frame<R: Rng + ?Sized>(
    width: usize,
    height: usize,
    blur: f64,
    noise: f64,
    rng: &mut R,
) -> Result<Vec<u8>, SynthError> {
    let mut canvas = Canvas::new(width, height, 128.0)?;
    // Textured background: coarse random grid, bilinearly upsampled.
    let g = 16usize;
    let (gw, gh) = (width / g + 2, height / g + 2);
    let grid: Vec<f32> = (0..gw * gh)
        .map(|_| rng.random_range(60.0..230.0))
        .collect();
    for y in 0..height {
        for x in 0..width {
            let (fx, fy) = (x as f32 / g as f32, y as f32 / g as f32);
            let (ix, iy) = (fx as usize, fy as usize);
            let (tx, ty) = (fx - ix as f32, fy - iy as f32);
            let at = |i: usize, j: usize| grid[j.min(gh - 1) * gw + i.min(gw - 1)];
            canvas.data[y * width + x] = (at(ix, iy) * (1.0 - tx) + at(ix + 1, iy) * tx)
                * (1.0 - ty)
                + (at(ix, iy + 1) * (1.0 - tx) + at(ix + 1, iy + 1) * tx) * ty;
        }
    }
    let (w, h) = (width as f64, height as f64);
    let shapes = rng.random_range(10..40usize);
    for _ in 0..shapes {
        let kind = rng.random_range(0..4u8);
        let cx = rng.random_range(0.0..w);
        let cy = rng.random_range(0.0..h);
        let theta = rng.random_range(0.0..std::f64::consts::TAU);
        let (s, c) = theta.sin_cos();
        let (sw, sh, pattern) = match kind {
            // Plain rectangle, dark or light.
            0 => {
                let p = CellPattern {
                    cols: 1,
                    rows: 1,
                    cells: vec![rng.random_bool(0.6)],
                    quiet_cells: 0.0,
                };
                (
                    rng.random_range(8.0..150.0),
                    rng.random_range(8.0..150.0),
                    p,
                )
            }
            // Black-bordered square with a random inside of random grid size (the markers'
            // own 4 x 5 included: such a square is a foreign marker of the family).
            1 => {
                let n = rng.random_range(1..8usize);
                let m = rng.random_range(1..8usize);
                let side = rng.random_range(15.0..130.0);
                (
                    side,
                    side * rng.random_range(0.7..1.4),
                    CellPattern::random_marker(n, m, rng),
                )
            }
            // Text-like stroke.
            2 => {
                let p = CellPattern {
                    cols: 1,
                    rows: 1,
                    cells: vec![true],
                    quiet_cells: 0.0,
                };
                (rng.random_range(2.0..6.0), rng.random_range(6.0..25.0), p)
            }
            // Checker patch.
            _ => {
                let p = CellPattern {
                    cols: 4,
                    rows: 4,
                    cells: (0..16).map(|i| (i / 4 + i % 4) % 2 == 0).collect(),
                    quiet_cells: 0.0,
                };
                let side = rng.random_range(20.0..100.0);
                (side, side, p)
            }
        };
        let q = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]].map(|[u, v]| {
            let (x, y) = (u * sw, v * sh);
            [cx + c * x - s * y, cy + s * x + c * y]
        });
        let dark = rng.random_range(5.0..70.0);
        let light = rng.random_range(150.0..250.0);
        canvas.draw_pattern(&pattern, &q, dark, light);
    }
    canvas.blur(blur);
    canvas.noise(noise, rng);
    Ok(canvas.to_gray())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn homography_maps_unit_corners() {
        let q = [[10.0, 12.0], [50.0, 8.0], [60.0, 70.0], [5.0, 55.0]];
        let h = homography_from_unit_square(&q).unwrap();
        for (u, p) in [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .iter()
            .zip(&q)
        {
            let m = apply(&h, u[0], u[1]);
            assert!((m[0] - p[0]).abs() < 1e-9 && (m[1] - p[1]).abs() < 1e-9);
        }
        assert!(homography_from_unit_square(&[[0.0, 0.0]; 4]).is_none());
    }

    #[test]
    fn axis_aligned_square_has_exact_area_coverage() {
        let mut c = Canvas::new(20, 20, 255.0).unwrap();
        let p = CellPattern {
            cols: 1,
            rows: 1,
            cells: vec![true],
            quiet_cells: 0.0,
        };
        // Edges at x = 4.25 and 14.75: pixels 4 and 15 are a quarter black.
        let q = [[4.25, 4.5], [14.75, 4.5], [14.75, 14.5], [4.25, 14.5]];
        assert!(c.draw_pattern(&p, &q, 0.0, 255.0));
        let g = c.to_gray();
        assert_eq!(g[10 * 20 + 10], 0);
        assert_eq!(g[10 * 20 + 4], 191); // 1/4 covered by black
        assert_eq!(g[10 * 20 + 14], 0);
        assert_eq!(g[10 * 20 + 15], 191);
        assert_eq!(g[10 * 20 + 2], 255);
    }

    #[test]
    fn scenes_are_reproducible_and_complete() {
        let cfg = SceneConfig::default();
        let a = random_marker_scene(&cfg, 4, 5, &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
        let b = random_marker_scene(&cfg, 4, 5, &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.markers.len(), 8);
        assert_eq!(a.pixels.len(), 640 * 480);
        let bad = SceneConfig {
            min_side: 50.0,
            max_side: 10.0,
            ..cfg
        };
        assert!(matches!(
            random_marker_scene(&bad, 4, 5, &mut ChaCha8Rng::seed_from_u64(1)),
            Err(SynthError::BadSides { .. })
        ));
        let crowded = SceneConfig {
            markers: 200,
            ..cfg
        };
        assert!(matches!(
            random_marker_scene(&crowded, 4, 5, &mut ChaCha8Rng::seed_from_u64(1)),
            Err(SynthError::NoRoom { .. })
        ));
    }
}
