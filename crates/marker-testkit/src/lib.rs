//! Seeded synthetic marker scenes with exact ground truth, for the detector's tests,
//! benchmarks and accuracy tables (`cargo xtask detector-accuracy`). Not published.
//!
//! There is one renderer in the workspace, `synthcam`; this crate only builds its scenes.
//! A marker (or any cell pattern) that should appear as the image quadrilateral `q` becomes
//! a `synthcam` [`Panel`]: the homography `H` taking the unit square to `q` is the view,
//! through a camera with intrinsics `K`, of the parallelogram `K^-1 H [u, v, 1]^T` (affine in
//! `(u, v)`), so the panel projects exactly onto `q` and the ground-truth corners are the
//! ones asked for, in the pixel-centre convention of spec 2.1. Supersampling (box filter,
//! multi-jittered samples), lighting gradient, Gaussian blur and seeded Gaussian noise are
//! `synthcam`'s.
//!
//! The crate knows nothing about dictionaries or families: a marker is a [`CellPattern`]
//! built from data bits (`bit k = row * cols + col`, black = 1, spec 3.1), so the detector's
//! own tests can use it without a dependency cycle. All randomness comes from the caller's
//! seeded RNG.
#![deny(missing_docs)]

pub mod edits;
pub mod reference;

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Vector3};
use rand::{Rng, RngExt};
use synthcam::{
    CellGrid, Filter, Gradient, ImageTexture, Panel, PosedCamera, RenderSettings, Scene, Texture,
};
use thiserror::Error;

/// Why a scene cannot be generated.
#[derive(Debug, Error)]
pub enum TestkitError {
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
    /// A marker index beyond the list of entries.
    #[error("marker index {index} is beyond the {entries} entries given")]
    NoEntry {
        /// The index asked for.
        index: usize,
        /// Entries given.
        entries: usize,
    },
    /// The synthetic camera refused the scene.
    #[error(transparent)]
    Render(#[from] synthcam::SynthError),
}

/// A rectangle of black and white cells (the whole marker, border included) with a white
/// quiet zone of `quiet_cells` cells around it.
#[derive(Debug, Clone, PartialEq)]
pub struct CellPattern {
    /// Cells across.
    pub cols: usize,
    /// Cells down.
    pub rows: usize,
    /// Row-major, `true` = black.
    pub cells: Vec<bool>,
    /// Width of the white quiet zone, in cells.
    pub quiet_cells: usize,
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
            quiet_cells: 1,
        }
    }

    /// The marker whose `data_rows x data_cols` data cells are the bits of `code` (bit
    /// `k = row * data_cols + col`, black = 1, spec 3.1), in a one-cell black border and a
    /// one-cell quiet zone: the cells a dictionary entry is drawn with.
    pub fn from_code(data_rows: usize, data_cols: usize, code: u64) -> Self {
        let bits: Vec<bool> = (0..data_rows * data_cols)
            .map(|k| k < 64 && (code >> k) & 1 == 1)
            .collect();
        Self::from_bits(data_rows, data_cols, &bits)
    }

    /// [`CellPattern::from_code`] of every code, in order: a dictionary's entries, so that
    /// an entry's index in the result is its index in the dictionary.
    pub fn from_codes(
        data_rows: usize,
        data_cols: usize,
        codes: impl IntoIterator<Item = u64>,
    ) -> Vec<Self> {
        codes
            .into_iter()
            .map(|code| Self::from_code(data_rows, data_cols, code))
            .collect()
    }

    /// A pattern of `rows x cols` cells and no quiet zone.
    pub fn plain(rows: usize, cols: usize, cells: Vec<bool>) -> Self {
        Self {
            cols,
            rows,
            cells,
            quiet_cells: 0,
        }
    }

    /// Width over height of the pattern (cells are square when drawn at this aspect).
    pub fn aspect(&self) -> f64 {
        self.cols as f64 / self.rows.max(1) as f64
    }

    /// The pattern with its quiet zone as a `synthcam` texture: black cells at grey level
    /// `black`, white cells and the quiet zone at `white`.
    fn texture(&self, black: u8, white: u8) -> Result<CellGrid, TestkitError> {
        let q = self.quiet_cells;
        let (rows, cols) = (self.rows + 2 * q, self.cols + 2 * q);
        let values = (0..rows * cols)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                let inside = (q..q + self.rows).contains(&r) && (q..q + self.cols).contains(&c);
                let is_black =
                    inside && self.cells.get((r - q) * self.cols + (c - q)).copied() == Some(true);
                if is_black { black } else { white }
            })
            .collect();
        Ok(CellGrid::new(rows, cols, values)?)
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

/// Optical and sensor effects of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects {
    /// Lighting ratio across the frame, left to right (1 = uniform, 4 = 4:1).
    pub lighting: f64,
    /// Optical blur sigma, pixels.
    pub blur: f64,
    /// Sensor noise sigma, grey levels.
    pub noise: f64,
    /// Noise seed.
    pub seed: u64,
    /// Samples per pixel side (`n x n` samples, each in its own row and column: an edge
    /// along a pixel axis lands within `1 / (2 n^2)` px).
    pub supersampling: usize,
}

impl Default for Effects {
    /// No lighting ramp, blur or noise; 8 x 8 samples per pixel.
    fn default() -> Self {
        Self {
            lighting: 1.0,
            blur: 0.0,
            noise: 0.0,
            seed: 0,
            supersampling: 8,
        }
    }
}

/// A frame being composed: a background and cell patterns drawn onto image quadrilaterals,
/// later ones on top. [`Canvas::render`] renders it through `synthcam`.
#[derive(Debug, Clone)]
pub struct Canvas {
    width: usize,
    height: usize,
    camera: PosedCamera,
    scene: Scene,
}

/// Focal length (px) of the canvas camera; any value works, since panels are placed to
/// project exactly onto the quadrilaterals asked for.
const CANVAS_FOCAL: f64 = 1000.0;

impl Canvas {
    /// A frame filled with grey level `value` (0-255).
    pub fn new(width: usize, height: usize, value: f64) -> Result<Self, TestkitError> {
        if width == 0 || height == 0 || width > 16_384 || height > 16_384 {
            return Err(TestkitError::BadSize { width, height });
        }
        let k = pose::Intrinsics::square_pixels(
            CANVAS_FOCAL,
            CANVAS_FOCAL,
            0.5 * (width as f64 - 1.0),
            0.5 * (height as f64 - 1.0),
        )
        .map_err(|_| TestkitError::BadSize { width, height })?;
        let camera = PosedCamera::new(k, width, height, Isometry3::identity())?;
        Ok(Self {
            width,
            height,
            camera,
            scene: Scene::new((value / 255.0).clamp(0.0, 1.0)),
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Places `texture` so that its unit square `[0, 1]^2` covers the image quadrilateral
    /// `quad` (NW, NE, SE, SW), with the texture's extent being `[-mu, 1 + mu] x [-mv, 1 + mv]`
    /// of that square. Returns `false` (drawing nothing) if the quadrilateral is degenerate
    /// or the extent would reach the horizon.
    fn place(&mut self, texture: Arc<dyn Texture>, quad: &[[f64; 2]; 4], mu: f64, mv: f64) -> bool {
        let Some(h) = homography_from_unit_square(quad) else {
            return false;
        };
        let k_inv = *self.camera.k_inv();
        let m = k_inv * h;
        let at = |u: f64, v: f64| m * Vector3::new(u, v, 1.0);
        let ext = [
            at(-mu, -mv),
            at(1.0 + mu, -mv),
            at(1.0 + mu, 1.0 + mv),
            at(-mu, 1.0 + mv),
        ];
        let zmin = ext.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        if !(zmin > 1e-6 && ext.iter().all(|p| p.iter().all(|c| c.is_finite()))) {
            return false;
        }
        // Later panels sit nearer the camera (scaling a panel about the camera centre does
        // not change its image), so they cover earlier ones.
        let n = self.scene.panels.len() as f64;
        let scale = 1e3 / (1.0 + n) / zmin;
        let p = |v: &Vector3<f64>| Point3::from(v * scale);
        self.scene
            .panels
            .push(Panel::new([p(&ext[0]), p(&ext[1]), p(&ext[3])], texture));
        true
    }

    /// Draws `pattern` (white cells and quiet zone at grey level `white`, black cells at
    /// `black`) onto the quadrilateral `corners` (images of the pattern's outer corners NW,
    /// NE, SE, SW; the quiet zone extends beyond). Returns `false` (drawing nothing) if the
    /// quadrilateral is degenerate.
    pub fn draw_pattern(
        &mut self,
        pattern: &CellPattern,
        corners: &[[f64; 2]; 4],
        black: f64,
        white: f64,
    ) -> bool {
        let level = |v: f64| v.round().clamp(0.0, 255.0) as u8;
        let Ok(texture) = pattern.texture(level(black), level(white)) else {
            return false;
        };
        let q = pattern.quiet_cells as f64;
        let mu = q / pattern.cols.max(1) as f64;
        let mv = q / pattern.rows.max(1) as f64;
        self.place(Arc::new(texture), corners, mu, mv)
    }

    /// Draws smooth textured noise over the whole frame: a grid of random grey levels from
    /// `grey` (one every 16 pixels, drawn row by row from `rng`), bilinearly upsampled. The
    /// clutter of [`clutter_frame`] and of `cargo xtask compare`'s scenes starts with it.
    pub fn draw_texture<R: Rng + ?Sized>(
        &mut self,
        grey: std::ops::Range<f64>,
        rng: &mut R,
    ) -> Result<bool, TestkitError> {
        let g = 16usize;
        let (gw, gh) = (self.width / g + 2, self.height / g + 2);
        let grid: Vec<u8> = (0..gw * gh)
            .map(|_| rng.random_range(grey.clone()).round() as u8)
            .collect();
        self.draw_bilinear(gw, gh, grid, g as f64)
    }

    /// Draws a grey image (row-major, `width x height`) bilinearly interpolated between its
    /// texel centres, which land `spacing` pixels apart with texel `(0, 0)` on pixel `(0, 0)`.
    pub fn draw_bilinear(
        &mut self,
        width: usize,
        height: usize,
        data: Vec<u8>,
        spacing: f64,
    ) -> Result<bool, TestkitError> {
        let texture = ImageTexture::new(width, height, data, Filter::Bilinear)?;
        // Texel centres at (i + 0.5) / width of the texture's extent.
        let (x0, y0) = (-0.5 * spacing, -0.5 * spacing);
        let (x1, y1) = (x0 + width as f64 * spacing, y0 + height as f64 * spacing);
        let quad = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
        Ok(self.place(Arc::new(texture), &quad, 0.0, 0.0))
    }

    /// Renders the frame: 8-bit grey, row-major.
    pub fn render(&self, effects: &Effects) -> Result<Vec<u8>, TestkitError> {
        let ratio = if effects.lighting.is_finite() && effects.lighting >= 1.0 {
            effects.lighting
        } else {
            1.0
        };
        let settings = RenderSettings {
            supersampling: effects.supersampling,
            gradient: (ratio > 1.0).then_some(Gradient {
                from: 1.0,
                to: 1.0 / ratio,
                angle: 0.0,
            }),
            blur_sigma: effects.blur.max(0.0),
            noise_sigma: effects.noise.max(0.0),
            seed: effects.seed,
            shading: None,
            ..RenderSettings::default()
        };
        Ok(synthcam::render(&self.scene, &self.camera, &settings)?
            .frame
            .data)
    }
}

/// True when the four corners form a convex quadrilateral, clockwise in the image (v down),
/// with every interior angle between `min_angle_deg` and `180 - min_angle_deg`.
fn convex_clockwise(c: &[[f64; 2]; 4], min_angle_deg: f64) -> bool {
    let max_cos = min_angle_deg.to_radians().cos();
    (0..4).all(|i| {
        let (a, b, d) = (c[(i + 3) % 4], c[i], c[(i + 1) % 4]);
        let e1 = [b[0] - a[0], b[1] - a[1]];
        let e2 = [d[0] - b[0], d[1] - b[1]];
        let cross = e1[0] * e2[1] - e1[1] * e2[0];
        let n1 = e1[0].hypot(e1[1]);
        let n2 = e2[0].hypot(e2[1]);
        cross > 0.0
            && n1 > 0.0
            && n2 > 0.0
            && (-(e1[0] * e2[0] + e1[1] * e2[1]) / (n1 * n2)).abs() <= max_cos
    })
}

/// The smallest interior angle of the quadrilateral `c`, degrees: how sharp the sharpest
/// corner of a marker's outline is (a marker seen at a grazing angle is a thin
/// parallelogram with two sharp corners).
pub fn sharpest_corner_deg(c: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| {
            let (p, a, b) = (c[i], c[(i + 3) % 4], c[(i + 1) % 4]);
            let (u, v) = ([a[0] - p[0], a[1] - p[1]], [b[0] - p[0], b[1] - p[1]]);
            let cos = (u[0] * v[0] + u[1] * v[1]) / (u[0].hypot(u[1]) * v[0].hypot(v[1]));
            cos.clamp(-1.0, 1.0).acos().to_degrees()
        })
        .fold(180.0, f64::min)
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
    pub black: f64,
    /// Grey level of white cells and background (before lighting).
    pub white: f64,
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
    /// Its index in the caller's list of entries, for [`marker_scene`].
    pub index: Option<usize>,
    /// Exact image corners NW, NE, SE, SW of the black border's outer edge (pixel centres).
    pub corners: [Point2<f64>; 4],
}

/// A rendered scene: 8-bit grey pixels and ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerScene {
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
) -> Result<Vec<[[f64; 2]; 4]>, TestkitError> {
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
        return Err(TestkitError::BadSize {
            width: cfg.width,
            height: cfg.height,
        });
    }
    if !(cfg.min_side > 0.0 && cfg.min_side <= cfg.max_side && cfg.max_side.is_finite()) {
        return Err(TestkitError::BadSides {
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
        if !convex_clockwise(&corners, 45.0) {
            continue;
        }
        placed.push((c, radius, corners));
    }
    if placed.len() < cfg.markers {
        return Err(TestkitError::NoRoom {
            placed: placed.len(),
            wanted: cfg.markers,
        });
    }
    Ok(placed.into_iter().map(|(_, _, q)| q).collect())
}

/// Renders `patterns` (one per placement, cycled) onto a white frame at random placements,
/// with lighting, blur and noise as configured.
pub fn render_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    patterns: &[CellPattern],
    rng: &mut R,
) -> Result<MarkerScene, TestkitError> {
    render_indexed(cfg, patterns, &[], rng)
}

/// A scene of the markers `entries[i]` for each `i` of `indices` (one per placement,
/// cycled), each [`PlacedMarker`] recording its index, at random placements drawn from
/// `rng`: with the markers chosen apart (another generator), two families rendered from
/// generators in the same state get the same placements, blur and noise (a paired
/// comparison), up to their patterns' aspect.
pub fn marker_scene_of<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    entries: &[CellPattern],
    indices: &[usize],
    rng: &mut R,
) -> Result<MarkerScene, TestkitError> {
    let patterns = indices
        .iter()
        .map(|&index| {
            entries.get(index).cloned().ok_or(TestkitError::NoEntry {
                index,
                entries: entries.len(),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    render_indexed(cfg, &patterns, indices, rng)
}

/// [`render_scene`] recording an index per pattern.
fn render_indexed<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    patterns: &[CellPattern],
    indices: &[usize],
    rng: &mut R,
) -> Result<MarkerScene, TestkitError> {
    let quiet = patterns
        .iter()
        .map(|p| p.quiet_cells as f64 / p.cols.min(p.rows).max(1) as f64)
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
    let pixels = canvas.render(&Effects {
        lighting: cfg.lighting,
        blur: cfg.blur,
        noise: cfg.noise,
        seed: rng.random(),
        ..Effects::default()
    })?;
    Ok(MarkerScene {
        width: cfg.width,
        height: cfg.height,
        pixels,
        markers,
    })
}

/// A scene of `cfg.markers` real markers: distinct random entries of `entries` (e.g. every
/// code of a dictionary as [`CellPattern::from_code`]) drawn with their true aspect (square
/// cells). Each [`PlacedMarker`] records its index in `entries`.
pub fn marker_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    entries: &[CellPattern],
    rng: &mut R,
) -> Result<MarkerScene, TestkitError> {
    let n = cfg.markers.max(1);
    let mut indices: Vec<usize> = Vec::with_capacity(n);
    while indices.len() < n {
        let i = rng.random_range(0..entries.len().max(1));
        if !indices.contains(&i) || indices.len() >= entries.len() {
            indices.push(i);
        }
    }
    let patterns: Vec<CellPattern> = indices
        .iter()
        .filter_map(|&i| entries.get(i).cloned())
        .collect();
    render_indexed(cfg, &patterns, &indices, rng)
}

/// A scene of `cfg.markers` random marker-like patterns (`data_rows x data_cols` random cells
/// inside a black border): the stand-in for real markers in corner-accuracy tests.
pub fn random_marker_scene<R: Rng + ?Sized>(
    cfg: &SceneConfig,
    data_rows: usize,
    data_cols: usize,
    rng: &mut R,
) -> Result<MarkerScene, TestkitError> {
    let patterns: Vec<CellPattern> = (0..cfg.markers.max(1))
        .map(|_| CellPattern::random_marker(data_rows, data_cols, rng))
        .collect();
    render_scene(cfg, &patterns, rng)
}

/// The markers a clutter frame must not contain by chance: the data grid of the detector's
/// family and a test for its codes.
///
/// Clutter draws black-bordered squares with random insides of every grid size, the
/// family's own included; one in about `2^(rows cols) / (4 entries)` of those is, by
/// chance, an exact dictionary entry, a real marker that any correct detector reads. Such
/// a square is redrawn, so that every code read in a clutter frame is a false read.
#[derive(Clone, Copy)]
pub struct NotMarkers<'a> {
    /// Data rows of the family's grid.
    pub rows: usize,
    /// Data columns of the family's grid.
    pub cols: usize,
    /// Whether a `rows x cols` code (`bit k = row * cols + col`, black = 1) is a marker in
    /// some orientation (the detector's own lookup, e.g. `lookup_within(code, 0)`). Grids
    /// drawn `cols x rows` are turned a quarter before the test.
    pub is_marker: &'a dyn Fn(u64) -> bool,
}

impl NotMarkers<'_> {
    /// Whether the bordered pattern `p` (one-cell border, as drawn by clutter) holds a
    /// marker of the family.
    fn rejects(&self, p: &CellPattern) -> bool {
        let (dr, dc) = (p.rows.saturating_sub(2), p.cols.saturating_sub(2));
        if self.rows * self.cols > 64 {
            return false; // no code of more than 64 bits reaches the test
        }
        let bit = |r: usize, c: usize| p.cells.get((r + 1) * p.cols + c + 1) == Some(&true);
        let code = if (dr, dc) == (self.rows, self.cols) {
            (0..dr * dc)
                .filter(|&k| bit(k / dc, k % dc))
                .map(|k| 1u64 << k)
                .sum()
        } else if (dc, dr) == (self.rows, self.cols) {
            // Turned a quarter clockwise: cell (r, c) of the result is cell (dr - 1 - c, r).
            (0..dr * dc)
                .filter(|&k| bit(dr - 1 - k % dr, k / dr))
                .map(|k| 1u64 << k)
                .sum()
        } else {
            return false;
        };
        (self.is_marker)(code)
    }
}

/// A marker-free clutter frame: smooth textured noise, random rectangles (some of them
/// black-bordered squares with random insides of any grid size, the hardest impostors),
/// checker patches and short dark strokes like text, then blur `blur` and noise `noise`.
/// Bordered squares that happen to be markers of `not` are redrawn ([`NotMarkers`]).
pub fn clutter_frame<R: Rng + ?Sized>(
    width: usize,
    height: usize,
    blur: f64,
    noise: f64,
    not: NotMarkers<'_>,
    rng: &mut R,
) -> Result<Vec<u8>, TestkitError> {
    let mut canvas = Canvas::new(width, height, 128.0)?;
    canvas.draw_texture(60.0..230.0, rng)?;
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
                let p = CellPattern::plain(1, 1, vec![rng.random_bool(0.6)]);
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
                let mut p = CellPattern::random_marker(n, m, rng);
                while not.rejects(&p) {
                    p = CellPattern::random_marker(n, m, rng);
                }
                (side, side * rng.random_range(0.7..1.4), p)
            }
            // Text-like stroke.
            2 => {
                let p = CellPattern::plain(1, 1, vec![true]);
                (rng.random_range(2.0..6.0), rng.random_range(6.0..25.0), p)
            }
            // Checker patch.
            _ => {
                let p =
                    CellPattern::plain(4, 4, (0..16).map(|i| (i / 4 + i % 4) % 2 == 0).collect());
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
    canvas.render(&Effects {
        blur,
        noise,
        seed: rng.random(),
        ..Effects::default()
    })
}

/// Linear motion blur: each pixel becomes the mean of the frame along a segment of
/// `length` pixels centred on it at `angle` radians from the image's x axis (a box kernel,
/// as a camera moving uniformly while the shutter is open), sampled bilinearly every quarter
/// pixel with edge pixels replicated. The blur is symmetric, so marker corners stay where
/// they were. A `length` below one pixel (or not finite) returns the frame unchanged.
pub fn motion_blur(
    pixels: &[u8],
    width: usize,
    height: usize,
    length: f64,
    angle: f64,
) -> Result<Vec<u8>, TestkitError> {
    if width == 0 || height == 0 || width > 16384 || height > 16384 || pixels.len() < width * height
    {
        return Err(TestkitError::BadSize { width, height });
    }
    if !(length.is_finite() && length >= 1.0 && angle.is_finite()) {
        return Ok(pixels[..width * height].to_vec());
    }
    let samples = (4.0 * length).ceil() as usize + 1;
    let (dx, dy) = (angle.cos(), angle.sin());
    let offsets: Vec<(f64, f64)> = (0..samples)
        .map(|k| {
            let t = -0.5 * length + length * k as f64 / (samples - 1) as f64;
            (t * dx, t * dy)
        })
        .collect();
    let (wmax, hmax) = ((width - 1) as f64, (height - 1) as f64);
    let at = |x: f64, y: f64| -> f64 {
        let (x, y) = (x.clamp(0.0, wmax), y.clamp(0.0, hmax));
        let (xi, yi) = (x as usize, y as usize);
        let (fx, fy) = (x - xi as f64, y - yi as f64);
        let (xj, yj) = ((xi + 1).min(width - 1), (yi + 1).min(height - 1));
        let g = |xx: usize, yy: usize| f64::from(pixels[yy * width + xx]);
        let top = g(xi, yi) + (g(xj, yi) - g(xi, yi)) * fx;
        let bot = g(xi, yj) + (g(xj, yj) - g(xi, yj)) * fx;
        top + (bot - top) * fy
    };
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let sum: f64 = offsets
                .iter()
                .map(|&(ox, oy)| at(x as f64 + ox, y as f64 + oy))
                .sum();
            out.push((sum / samples as f64).round().clamp(0.0, 255.0) as u8);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // tests may unwrap (house rules)
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_sharpest_corner_of_a_square_and_of_a_thin_parallelogram() {
        let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        assert!((sharpest_corner_deg(&square) - 90.0).abs() < 1e-9);
        // Sides along x and at 20 degrees to it: corners of 20 and 160 degrees.
        let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
        let thin = [
            [0.0, 0.0],
            [30.0, 0.0],
            [30.0 + 9.0 * c, 9.0 * s],
            [9.0 * c, 9.0 * s],
        ];
        assert!((sharpest_corner_deg(&thin) - 20.0).abs() < 1e-9);
    }

    /// Two families rendered from generators in the same state share the placement (the
    /// paired comparison of `cargo xtask detector-accuracy`); an index beyond the entries is
    /// an error, not a panic.
    #[test]
    fn marker_scene_of_pairs_placements_and_checks_indices() {
        let cfg = SceneConfig {
            markers: 1,
            ..SceneConfig::default()
        };
        let own = vec![CellPattern::random_marker(
            4,
            5,
            &mut ChaCha8Rng::seed_from_u64(1),
        )];
        let tag = vec![
            CellPattern::random_marker(6, 6, &mut ChaCha8Rng::seed_from_u64(2)),
            CellPattern::random_marker(6, 6, &mut ChaCha8Rng::seed_from_u64(3)),
        ];
        let mut paired = 0;
        for seed in 0..20 {
            let a =
                marker_scene_of(&cfg, &own, &[0], &mut ChaCha8Rng::seed_from_u64(seed)).unwrap();
            let b =
                marker_scene_of(&cfg, &tag, &[1], &mut ChaCha8Rng::seed_from_u64(seed)).unwrap();
            assert_eq!((a.markers[0].index, b.markers[0].index), (Some(0), Some(1)));
            let centre = |m: &PlacedMarker| {
                m.corners
                    .iter()
                    .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords)
                    / 4.0
            };
            if (centre(&a.markers[0]) - centre(&b.markers[0])).norm() < 5.0 {
                paired += 1;
            }
        }
        assert!(paired >= 10, "only {paired} of 20 placements shared");
        assert!(matches!(
            marker_scene_of(&cfg, &own, &[1], &mut ChaCha8Rng::seed_from_u64(0)),
            Err(TestkitError::NoEntry {
                index: 1,
                entries: 1
            })
        ));
    }

    #[test]
    fn homography_maps_unit_corners() {
        let q = [[10.0, 12.0], [50.0, 8.0], [60.0, 70.0], [5.0, 55.0]];
        let h = homography_from_unit_square(&q).unwrap();
        for (u, p) in [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .iter()
            .zip(&q)
        {
            let m = h * Vector3::new(u[0], u[1], 1.0);
            assert!((m.x / m.z - p[0]).abs() < 1e-9 && (m.y / m.z - p[1]).abs() < 1e-9);
        }
        assert!(homography_from_unit_square(&[[0.0, 0.0]; 4]).is_none());
    }

    #[test]
    fn axis_aligned_square_has_exact_area_coverage() {
        let mut c = Canvas::new(20, 20, 255.0).unwrap();
        let p = CellPattern::plain(1, 1, vec![true]);
        // Edges at x = 4.25 and 14.75: pixels 4 and 15 are a quarter black.
        let q = [[4.25, 4.5], [14.75, 4.5], [14.75, 14.5], [4.25, 14.5]];
        assert!(c.draw_pattern(&p, &q, 0.0, 255.0));
        let g = c.render(&Effects::default()).unwrap();
        assert_eq!(g[10 * 20 + 10], 0);
        assert_eq!(g[10 * 20 + 4], 191); // 1/4 covered by black
        assert_eq!(g[10 * 20 + 14], 0);
        assert_eq!(g[10 * 20 + 15], 191);
        assert_eq!(g[10 * 20 + 2], 255);
    }

    #[test]
    fn later_patterns_cover_earlier_ones() {
        let mut c = Canvas::new(20, 20, 255.0).unwrap();
        let black = CellPattern::plain(1, 1, vec![true]);
        let white = CellPattern::plain(1, 1, vec![false]);
        let big = [[2.0, 2.0], [17.0, 2.0], [17.0, 17.0], [2.0, 17.0]];
        let small = [[6.0, 6.0], [13.0, 6.0], [13.0, 13.0], [6.0, 13.0]];
        assert!(c.draw_pattern(&black, &big, 10.0, 200.0));
        assert!(c.draw_pattern(&white, &small, 10.0, 200.0));
        let g = c.render(&Effects::default()).unwrap();
        assert_eq!(g[4 * 20 + 4], 10);
        assert_eq!(g[10 * 20 + 10], 200);
        assert_eq!(g[0], 255);
    }

    #[test]
    fn clutter_redraws_chance_markers_in_either_aspect() {
        // A 4 x 5 code, drawn as is and turned a quarter counter-clockwise (5 x 4).
        let x: u64 = 0b1011_0010_1110_0101_0011;
        let bit = |r: usize, c: usize| x >> (r * 5 + c) & 1 == 1;
        let as_is: Vec<bool> = (0..20).map(|k| bit(k / 5, k % 5)).collect();
        let turned: Vec<bool> = (0..20).map(|k| bit(k % 4, 4 - k / 4)).collect();
        let is_x = |code: u64| code == x;
        let not = NotMarkers {
            rows: 4,
            cols: 5,
            is_marker: &is_x,
        };
        assert!(not.rejects(&CellPattern::from_bits(4, 5, &as_is)));
        assert!(not.rejects(&CellPattern::from_bits(5, 4, &turned)));
        let mut other = as_is.clone();
        other[7] = !other[7];
        assert!(!not.rejects(&CellPattern::from_bits(4, 5, &other)));
        assert!(!not.rejects(&CellPattern::from_bits(4, 4, &as_is[..16])));
        // A test that calls half of all codes markers only costs redraws.
        let half = |code: u64| code & 1 == 1;
        let frame = clutter_frame(
            160,
            120,
            1.0,
            3.0,
            NotMarkers {
                rows: 4,
                cols: 5,
                is_marker: &half,
            },
            &mut ChaCha8Rng::seed_from_u64(3),
        )
        .unwrap();
        assert_eq!(frame.len(), 160 * 120);
    }

    #[test]
    fn motion_blur_spreads_an_edge_along_its_direction_only() {
        // A vertical edge at x = 10 (dark left, light right) in a 20 x 5 frame.
        let (w, h) = (20, 5);
        let frame: Vec<u8> = (0..w * h)
            .map(|i| if i % w < 10 { 0 } else { 200 })
            .collect();
        // Blurred across the edge (horizontally, 5 px): a ramp about 5 px wide, centred.
        let across = motion_blur(&frame, w, h, 5.0, 0.0).unwrap();
        let row = &across[2 * w..3 * w];
        assert_eq!(row[3], 0);
        assert_eq!(row[16], 200);
        assert!(row[8] > 0 && row[8] < 100, "{row:?}");
        assert!(row[11] > 100 && row[11] < 200, "{row:?}");
        // Symmetric: the two pixels either side of the edge sum to the light level.
        assert!(
            (i32::from(row[9]) + i32::from(row[10]) - 200).abs() <= 2,
            "{row:?}"
        );
        // Along the edge (vertically) nothing changes.
        assert_eq!(
            motion_blur(&frame, w, h, 5.0, std::f64::consts::FRAC_PI_2).unwrap(),
            frame
        );
        // Bad sizes are errors, short blurs no-ops.
        assert!(motion_blur(&frame, 0, h, 5.0, 0.0).is_err());
        assert!(motion_blur(&frame[..10], w, h, 5.0, 0.0).is_err());
        assert_eq!(motion_blur(&frame, w, h, 0.5, 0.0).unwrap(), frame);
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
            Err(TestkitError::BadSides { .. })
        ));
        let crowded = SceneConfig {
            markers: 200,
            ..cfg
        };
        assert!(matches!(
            random_marker_scene(&crowded, 4, 5, &mut ChaCha8Rng::seed_from_u64(1)),
            Err(TestkitError::NoRoom { .. })
        ));
    }
}
