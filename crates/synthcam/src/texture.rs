//! Textures: grey albedo as a function of face coordinates.
//!
//! A texture maps face coordinates `(s, t)` in `[0, 1]^2` to an albedo in `[0, 1]`
//! (0 black, 1 white). `s` grows to the right and `t` downward *as seen from outside the face*,
//! so a texture reads like an image pinned to the face: `(0, 0)` is the NW corner, `(1, 1)` the
//! SE corner. The renderer only calls [`Texture::albedo`] with `s, t` inside `[0, 1]`, but every
//! implementation here clamps anyway, so no input can make it panic or index out of bounds.

use crate::error::{SynthError, in_range};

/// A grey texture on a planar face.
pub trait Texture: Send + Sync + std::fmt::Debug {
    /// Albedo in `[0, 1]` at face coordinates `(s, t)` (`s` right, `t` down, both in `[0, 1]`).
    fn albedo(&self, s: f64, t: f64) -> f32;
}

/// Cell index along one axis for a coordinate in `[0, 1]` and `n` cells; clamps.
#[inline]
fn cell(x: f64, n: usize) -> usize {
    // `as usize` saturates: NaN and negatives become 0.
    let i = (x * n as f64) as usize;
    i.min(n - 1)
}

/// One albedo everywhere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Uniform {
    albedo: f32,
}

impl Uniform {
    /// A uniform texture; `albedo` must be in `[0, 1]`.
    pub fn new(albedo: f64) -> Result<Self, SynthError> {
        in_range("uniform albedo", albedo, 0.0, 1.0)?;
        Ok(Self {
            albedo: albedo as f32,
        })
    }
    /// The albedo.
    pub fn value(&self) -> f32 {
        self.albedo
    }
}

impl Texture for Uniform {
    #[inline]
    fn albedo(&self, _s: f64, _t: f64) -> f32 {
        self.albedo
    }
}

/// A grid of uniform cells with exact edges: `rows x cols` grey levels (0 black, 255 white),
/// row-major, row 0 at the top and column 0 at the left as seen from outside the face.
///
/// This is how a fiducial marker (black border, data cells, white quiet zone) is supplied: the
/// cell edges fall exactly at `s = col / cols` and `t = row / rows`, with no filtering, so the
/// only blur in the image is the renderer's own pixel box filter (plus optional optical blur).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CellGrid {
    rows: usize,
    cols: usize,
    values: Vec<u8>,
}

impl CellGrid {
    /// A cell grid from row-major grey levels; `values.len()` must equal `rows * cols > 0`.
    pub fn new(rows: usize, cols: usize, values: Vec<u8>) -> Result<Self, SynthError> {
        if rows == 0 || cols == 0 {
            return Err(SynthError::InvalidTexture {
                reason: "a cell grid needs at least one row and one column",
                rows,
                cols,
                len: values.len(),
            });
        }
        if rows.checked_mul(cols) != Some(values.len()) {
            return Err(SynthError::InvalidTexture {
                reason: "values.len() must equal rows * cols",
                rows,
                cols,
                len: values.len(),
            });
        }
        Ok(Self { rows, cols, values })
    }

    /// A grid from a black/white pattern: `true` is black (0), `false` white (255).
    pub fn from_bits(rows: usize, cols: usize, black: &[bool]) -> Result<Self, SynthError> {
        Self::new(
            rows,
            cols,
            black.iter().map(|&b| if b { 0 } else { 255 }).collect(),
        )
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }
    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// Row-major grey levels.
    pub fn values(&self) -> &[u8] {
        &self.values
    }
    /// Grey level of cell `(row, col)`, or `None` outside the grid.
    pub fn get(&self, row: usize, col: usize) -> Option<u8> {
        if row < self.rows && col < self.cols {
            self.values.get(row * self.cols + col).copied()
        } else {
            None
        }
    }
}

impl Texture for CellGrid {
    #[inline]
    fn albedo(&self, s: f64, t: f64) -> f32 {
        let r = cell(t, self.rows);
        let c = cell(s, self.cols);
        // Indices are clamped by `cell`, the length checked in `new`.
        self.values
            .get(r * self.cols + c)
            .map_or(0.0, |&v| f32::from(v) / 255.0)
    }
}

/// How an [`ImageTexture`] is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Filter {
    /// The nearest texel (crisp texel edges).
    #[default]
    Nearest,
    /// Bilinear interpolation between the four nearest texel centres (edges clamped).
    Bilinear,
}

/// A grey image stretched over the face: texel `(0, 0)` at the NW corner, row-major, 0 black,
/// 255 white.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    width: usize,
    height: usize,
    data: Vec<u8>,
    filter: Filter,
}

impl ImageTexture {
    /// An image texture; `data.len()` must equal `width * height > 0`.
    pub fn new(
        width: usize,
        height: usize,
        data: Vec<u8>,
        filter: Filter,
    ) -> Result<Self, SynthError> {
        if width == 0 || height == 0 || width.checked_mul(height) != Some(data.len()) {
            return Err(SynthError::InvalidTexture {
                reason: "an image texture needs width * height == data.len() > 0",
                rows: height,
                cols: width,
                len: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
            filter,
        })
    }
    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// The filter.
    pub fn filter(&self) -> Filter {
        self.filter
    }
    #[inline]
    fn texel(&self, x: usize, y: usize) -> f32 {
        self.data
            .get(y * self.width + x)
            .map_or(0.0, |&v| f32::from(v))
    }
}

impl Texture for ImageTexture {
    fn albedo(&self, s: f64, t: f64) -> f32 {
        match self.filter {
            Filter::Nearest => self.texel(cell(s, self.width), cell(t, self.height)) / 255.0,
            Filter::Bilinear => {
                // Texel centres at (i + 0.5) / width. NaN coordinates read the NW texel (a NaN
                // would otherwise survive `clamp` and poison the result).
                let (s, t) = (
                    if s.is_nan() { 0.0 } else { s },
                    if t.is_nan() { 0.0 } else { t },
                );
                let x = (s.clamp(0.0, 1.0) * self.width as f64 - 0.5)
                    .clamp(0.0, (self.width - 1) as f64);
                let y = (t.clamp(0.0, 1.0) * self.height as f64 - 0.5)
                    .clamp(0.0, (self.height - 1) as f64);
                let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
                let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
                let top = self.texel(x0, y0) * (1.0 - fx) + self.texel(x1, y0) * fx;
                let bottom = self.texel(x0, y1) * (1.0 - fx) + self.texel(x1, y1) * fx;
                (top * (1.0 - fy) + bottom * fy) / 255.0
            }
        }
    }
}

/// A soft, low-contrast checker for the ground: one period is a 2 x 2 checker whose cells
/// blend smoothly into each other (a product of two triangle waves), so it has texture for the
/// eye but no sharp, marker-like edges or corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftChecker {
    mean: f32,
    amplitude: f32,
}

impl SoftChecker {
    /// Albedo varies between `low` and `high` (both in `[0, 1]`, either order).
    pub fn new(low: f64, high: f64) -> Result<Self, SynthError> {
        in_range("soft checker low", low, 0.0, 1.0)?;
        in_range("soft checker high", high, 0.0, 1.0)?;
        Ok(Self {
            mean: ((low + high) / 2.0) as f32,
            amplitude: ((high - low) / 2.0) as f32,
        })
    }
}

/// Triangle wave with period 1: +1 at 0.25, -1 at 0.75, 0 at 0 and 0.5; 0 for non-finite `x`.
#[inline]
fn triangle(x: f64) -> f32 {
    if !x.is_finite() {
        return 0.0;
    }
    let f = x - x.floor();
    (if f < 0.5 {
        1.0 - (4.0 * f - 1.0).abs()
    } else {
        (4.0 * f - 3.0).abs() - 1.0
    }) as f32
}

impl Texture for SoftChecker {
    #[inline]
    fn albedo(&self, s: f64, t: f64) -> f32 {
        self.mean + self.amplitude * triangle(s) * triangle(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_grid_has_exact_cell_edges() {
        let g = CellGrid::new(2, 4, vec![0, 10, 20, 30, 40, 50, 60, 70]).unwrap();
        // Just left / right of the edge between columns 0 and 1 (s = 0.25).
        assert_eq!(g.albedo(0.25 - 1e-12, 0.1), 0.0);
        assert_eq!(g.albedo(0.25 + 1e-12, 0.1), 10.0 / 255.0);
        // Row edge at t = 0.5.
        assert_eq!(g.albedo(0.9, 0.5 - 1e-12), 30.0 / 255.0);
        assert_eq!(g.albedo(0.9, 0.5 + 1e-12), 70.0 / 255.0);
        // Out-of-range coordinates clamp rather than panic.
        assert_eq!(g.albedo(-3.0, 7.0), 40.0 / 255.0);
        assert_eq!(g.albedo(f64::NAN, f64::NAN), 0.0);
        assert_eq!(g.get(1, 3), Some(70));
        assert_eq!(g.get(2, 0), None);
    }

    #[test]
    fn bad_texture_sizes_are_errors() {
        assert!(matches!(
            CellGrid::new(0, 3, vec![]),
            Err(SynthError::InvalidTexture { .. })
        ));
        assert!(matches!(
            CellGrid::new(2, 2, vec![0; 3]),
            Err(SynthError::InvalidTexture { len: 3, .. })
        ));
        assert!(ImageTexture::new(2, 2, vec![0; 5], Filter::Nearest).is_err());
        assert!(Uniform::new(1.5).is_err());
        assert!(Uniform::new(f64::NAN).is_err());
        assert!(SoftChecker::new(-0.1, 0.5).is_err());
    }

    #[test]
    fn bilinear_interpolates_between_texel_centres() {
        let img = ImageTexture::new(2, 1, vec![0, 255], Filter::Bilinear).unwrap();
        // Texel centres at s = 0.25 and 0.75; halfway between is mid-grey.
        assert!((img.albedo(0.5, 0.5) - 0.5).abs() < 1e-6);
        assert_eq!(img.albedo(0.1, 0.5), 0.0);
        assert_eq!(img.albedo(0.9, 0.5), 1.0);
        let nearest = ImageTexture::new(2, 1, vec![0, 255], Filter::Nearest).unwrap();
        assert_eq!(nearest.albedo(0.49, 0.5), 0.0);
        assert_eq!(nearest.albedo(0.51, 0.5), 1.0);
        // Regression (found by proptest): NaN coordinates gave a NaN albedo.
        assert_eq!(img.albedo(0.0, f64::NAN), 0.0);
        assert_eq!(img.albedo(f64::NAN, 0.3), 0.0);
    }

    #[test]
    fn soft_checker_stays_within_its_range_and_varies() {
        let c = SoftChecker::new(0.4, 0.6).unwrap();
        let mut lo = f32::MAX;
        let mut hi = f32::MIN;
        for i in 0..100 {
            for j in 0..100 {
                let a = c.albedo(i as f64 * 0.031 - 1.3, j as f64 * 0.017 + 4.0);
                lo = lo.min(a);
                hi = hi.max(a);
            }
        }
        assert!(lo >= 0.4 - 1e-6 && hi <= 0.6 + 1e-6);
        assert!(hi - lo > 0.15);
        assert_eq!(c.albedo(f64::NAN, f64::INFINITY), 0.5);
    }
}
