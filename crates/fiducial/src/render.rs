//! Marker images: exact grey rasters (for tests, the synthetic camera and printing as PNG)
//! and SVG (vector, for printing at a physical size).
//!
//! Raster geometry is exact: every cell is `px_per_cell x px_per_cell` pixels, the quiet
//! zone is `quiet_cells` cells wide on every side, and the outer corners of the black
//! border are returned in the pixel-centre convention of spec 2.1 (integer coordinates
//! are pixel centres), so a border starting at pixel column `x0` has its edge at
//! `x0 - 0.5`.

use nalgebra::Point2;

use crate::error::FiducialError;
use crate::family::MarkerFamily;
use crate::image::{Corners, GrayView};

/// Grey level of black cells and the border.
pub(crate) const BLACK: u8 = 0;
/// Grey level of white cells and the quiet zone.
pub(crate) const WHITE: u8 = 255;

/// Raster layout of a rendered marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderOptions {
    /// Pixels per cell side (1..=1024).
    pub px_per_cell: u32,
    /// Width of the white quiet zone in cells (at least 1, at most 16).
    pub quiet_cells: u32,
}

impl Default for RenderOptions {
    /// 20 pixels per cell, a one-cell quiet zone.
    fn default() -> Self {
        Self {
            px_per_cell: 20,
            quiet_cells: 1,
        }
    }
}

/// A rendered marker: an owned grey raster plus the exact outer-border corners.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedMarker {
    pixels: Vec<u8>,
    width: usize,
    height: usize,
    corners: Corners,
}

impl RenderedMarker {
    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixels, row-major, tightly packed.
    pub fn pixels(&self) -> &[u8] {
        &self.pixels
    }

    /// Outer corners of the black border (NW, NE, SE, SW), pixel-centre convention.
    pub fn corners(&self) -> Corners {
        self.corners
    }

    /// A view of the raster for the decoder and detector.
    pub fn view(&self) -> GrayView<'_> {
        GrayView::new(&self.pixels, self.width, self.height)
            .expect("a rendered marker is a valid image by construction")
    }

    /// The raster as an [`image::GrayImage`] (e.g. to save as PNG).
    pub fn into_gray_image(self) -> image::GrayImage {
        let (w, h) = (self.width as u32, self.height as u32);
        image::GrayImage::from_raw(w, h, self.pixels)
            .expect("buffer length equals width * height by construction")
    }
}

fn check(family: MarkerFamily, code: u64, quiet_cells: u32) -> Result<(), FiducialError> {
    family.check_code(code)?;
    if !(1..=16).contains(&quiet_cells) {
        return Err(FiducialError::BadRender {
            reason: format!("quiet zone of {quiet_cells} cells; use 1..=16"),
        });
    }
    Ok(())
}

/// Whether marker cell `(x, y)` (border included, `0..width_cells`) is black.
#[inline]
fn cell_is_black(family: MarkerFamily, code: u64, x: u32, y: u32) -> bool {
    let (w, h) = (family.width_cells(), family.height_cells());
    if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
        return true;
    }
    family.bit(code, y - 1, x - 1)
}

/// Renders `code` of `family` as a grey raster (black 0, white 255).
pub fn render_marker(
    family: MarkerFamily,
    code: u64,
    options: &RenderOptions,
) -> Result<RenderedMarker, FiducialError> {
    check(family, code, options.quiet_cells)?;
    let k = options.px_per_cell;
    if !(1..=1024).contains(&k) {
        return Err(FiducialError::BadRender {
            reason: format!("{k} pixels per cell; use 1..=1024"),
        });
    }
    let q = options.quiet_cells;
    let wc = family.width_cells() + 2 * q;
    let hc = family.height_cells() + 2 * q;
    let (width, height) = ((wc * k) as usize, (hc * k) as usize);
    if width > GrayView::MAX_SIDE || height > GrayView::MAX_SIDE {
        return Err(FiducialError::BadRender {
            reason: format!(
                "a {width}x{height} image exceeds {} pixels a side",
                GrayView::MAX_SIDE
            ),
        });
    }
    let mut pixels = vec![WHITE; width * height];
    for (y, row) in pixels.chunks_exact_mut(width).enumerate() {
        let cy = y as u32 / k;
        if cy < q || cy >= q + family.height_cells() {
            continue;
        }
        for (x, px) in row.iter_mut().enumerate() {
            let cx = x as u32 / k;
            if cx >= q
                && cx < q + family.width_cells()
                && cell_is_black(family, code, cx - q, cy - q)
            {
                *px = BLACK;
            }
        }
    }
    let x0 = f64::from(q * k) - 0.5;
    let y0 = x0;
    let x1 = f64::from((q + family.width_cells()) * k) - 0.5;
    let y1 = f64::from((q + family.height_cells()) * k) - 0.5;
    Ok(RenderedMarker {
        pixels,
        width,
        height,
        corners: [
            Point2::new(x0, y0),
            Point2::new(x1, y0),
            Point2::new(x1, y1),
            Point2::new(x0, y1),
        ],
    })
}

/// Renders `code` as an SVG document sized for printing: each cell `cell_mm` millimetres,
/// a white quiet zone of `quiet_cells` cells. Black cells are merged into horizontal runs
/// and drawn with `shape-rendering="crispEdges"`.
pub fn render_svg(
    family: MarkerFamily,
    code: u64,
    cell_mm: f64,
    quiet_cells: u32,
) -> Result<String, FiducialError> {
    check(family, code, quiet_cells)?;
    if !(cell_mm.is_finite() && cell_mm > 0.0 && cell_mm <= 1000.0) {
        return Err(FiducialError::BadRender {
            reason: format!("cell size {cell_mm} mm; use a finite size in (0, 1000] mm"),
        });
    }
    let q = quiet_cells;
    let wc = family.width_cells() + 2 * q;
    let hc = family.height_cells() + 2 * q;
    let mut s = String::new();
    s.push_str(&format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}mm\" height=\"{h}mm\" \
         viewBox=\"0 0 {wc} {hc}\" shape-rendering=\"crispEdges\">\n\
         <!-- marker {rows}x{cols}, code {code}; cell {cell_mm} mm; black border {bw} x {bh} mm -->\n\
         <rect x=\"0\" y=\"0\" width=\"{wc}\" height=\"{hc}\" fill=\"#fff\"/>\n",
        w = f64::from(wc) * cell_mm,
        h = f64::from(hc) * cell_mm,
        rows = family.rows(),
        cols = family.cols(),
        bw = f64::from(family.width_cells()) * cell_mm,
        bh = f64::from(family.height_cells()) * cell_mm,
    ));
    for y in 0..family.height_cells() {
        let mut x = 0;
        while x < family.width_cells() {
            if cell_is_black(family, code, x, y) {
                let start = x;
                while x < family.width_cells() && cell_is_black(family, code, x, y) {
                    x += 1;
                }
                s.push_str(&format!(
                    "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"1\" fill=\"#000\"/>\n",
                    start + q,
                    y + q,
                    x - start
                ));
            } else {
                x += 1;
            }
        }
    }
    s.push_str("</svg>\n");
    Ok(s)
}
