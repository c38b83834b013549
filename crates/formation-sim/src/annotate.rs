//! Annotated frames, as in the paper's Figs. 10-11: the markers read (outlined and labelled
//! with robot and face) and each robot's estimated rig (the 3D outlines of its faces)
//! reprojected over the image.
//!
//! Drawing uses `imageproc` (lines, text with the DejaVu Sans font checked in under
//! `assets/fonts`, compiled into the binary). Projection is the plain pinhole
//! `K (R p + t)`, so a wrong pose shows as a rig drawn off its markers.

use ab_glyph::FontRef;
use image::{GrayImage, Rgb, RgbImage};
use imageproc::drawing::{draw_line_segment_mut, draw_text_mut};
use nalgebra::{Point2, Point3, Rotation3, Vector3};
use thiserror::Error;

use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotMeasurement;

static FONT_BYTES: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Why a frame could not be annotated.
#[derive(Debug, Error)]
pub enum AnnotateError {
    /// The embedded font did not load (a build problem, not a user one).
    #[error("the embedded DejaVu Sans font is invalid")]
    Font,
    /// The rig has invalid geometry.
    #[error(transparent)]
    Rig(#[from] formation_tracker::rig::RigError),
}

/// A marker read in the frame, to outline and label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerLabel {
    /// Robot number.
    pub robot: u32,
    /// Face number.
    pub face: u8,
    /// Corners NW, NE, SE, SW, pixels.
    pub corners: [Point2<f64>; 4],
}

/// A robot's estimated pose, to draw its rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigOverlay {
    /// Robot number.
    pub robot: u32,
    /// Rotation vector, rig frame to camera frame.
    pub rotation: [f64; 3],
    /// Translation, metres, camera frame.
    pub translation: [f64; 3],
}

impl From<&RobotMeasurement> for RigOverlay {
    /// The rig of a measured robot, drawn at its estimated pose.
    fn from(m: &RobotMeasurement) -> Self {
        Self {
            robot: m.robot,
            rotation: m.rotation,
            translation: m.translation,
        }
    }
}

/// A colour per robot (cycled).
fn robot_colour(robot: u32) -> Rgb<u8> {
    const C: [[u8; 3]; 6] = [
        [0, 220, 80],
        [0, 170, 255],
        [255, 80, 220],
        [255, 200, 0],
        [160, 110, 255],
        [0, 230, 230],
    ];
    Rgb(C[(robot.saturating_sub(1) as usize) % C.len()])
}

fn segment(img: &mut RgbImage, a: Point2<f64>, b: Point2<f64>, colour: Rgb<u8>) {
    let limit = 4.0 * f64::from(img.width().max(img.height()));
    let ok = |p: Point2<f64>| {
        p.x.is_finite() && p.y.is_finite() && p.x.abs() < limit && p.y.abs() < limit
    };
    if ok(a) && ok(b) {
        draw_line_segment_mut(
            img,
            (a.x as f32, a.y as f32),
            (b.x as f32, b.y as f32),
            colour,
        );
    }
}

fn polygon(img: &mut RgbImage, pts: &[Point2<f64>], colour: Rgb<u8>, thick: bool) {
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        segment(img, a, b, colour);
        if thick {
            let d = Vector3::new(b.x - a.x, b.y - a.y, 0.0);
            let n = Vector3::new(-d.y, d.x, 0.0)
                .try_normalize(1e-9)
                .unwrap_or_default();
            let o = nalgebra::Vector2::new(n.x, n.y);
            segment(img, a + o, b + o, colour);
        }
    }
}

/// Projects camera-frame points through `camera` ([`pose::Camera::project`]); `None` if any
/// is behind the camera.
fn project(camera: &pose::Camera, pts: &[Point3<f64>]) -> Option<Vec<Point2<f64>>> {
    pts.iter().map(|p| camera.project(p).ok()).collect()
}

/// Draws `markers` and `rigs` over a grey frame seen through `camera`.
pub fn annotate(
    frame: &GrayImage,
    camera: &pose::Camera,
    rig: &RigModel,
    markers: &[MarkerLabel],
    rigs: &[RigOverlay],
) -> Result<RgbImage, AnnotateError> {
    let font = FontRef::try_from_slice(FONT_BYTES).map_err(|_| AnnotateError::Font)?;
    let mut img = RgbImage::from_fn(frame.width(), frame.height(), |x, y| {
        let v = frame.get_pixel(x, y).0[0];
        Rgb([v, v, v])
    });
    let geometries = rig.face_geometries()?;
    let half_w = rig.geometry.face_width_m / 2.0;
    let cell = rig.geometry.cell_size_m;
    let [_, marker_h] = rig.geometry.marker_size_m()?;
    let half_h = marker_h / 2.0 + cell;
    for overlay in rigs {
        let colour = robot_colour(overlay.robot);
        let r = Rotation3::new(Vector3::from(overlay.rotation));
        let t = Vector3::from(overlay.translation);
        let to_cam = |p: Point3<f64>| r * p + t;
        for g in &geometries {
            let n = Vector3::from(g.normal);
            let c = Point3::from(g.centre);
            let right = Vector3::z().cross(&n);
            let up = Vector3::z();
            let panel = [
                c - right * half_w + up * half_h,
                c + right * half_w + up * half_h,
                c + right * half_w - up * half_h,
                c - right * half_w - up * half_h,
            ];
            let cam: Vec<Point3<f64>> = panel.iter().map(|&p| to_cam(p)).collect();
            // Faces turned away are drawn thin, faces towards the camera thick.
            let towards = (r * n).dot(&(-to_cam(c).coords)) > 0.0;
            if let Some(px) = project(camera, &cam) {
                polygon(&mut img, &px, colour, towards);
            }
            let border: Vec<Point3<f64>> = g.corner_points().iter().map(|&p| to_cam(p)).collect();
            if towards && let Some(px) = project(camera, &border) {
                polygon(&mut img, &px, colour, false);
            }
        }
        // The robot's vertical axis from the ground up to its faces (not over the markers),
        // and its number above the rig.
        let top = rig.geometry.marker_centre_height_m + half_h;
        let bottom = rig.geometry.marker_centre_height_m - half_h;
        if let Some(px) = project(
            camera,
            &[
                to_cam(Point3::origin()),
                to_cam(Point3::new(0.0, 0.0, bottom.max(0.0))),
                to_cam(Point3::new(0.0, 0.0, top)),
            ],
        ) {
            segment(&mut img, px[0], px[1], colour);
            draw_text_mut(
                &mut img,
                colour,
                px[2].x as i32 - 10,
                px[2].y as i32 - 34,
                16.0,
                &font,
                &format!("R{}", overlay.robot),
            );
        }
    }
    let label_colour = Rgb([255, 40, 40]);
    for m in markers {
        polygon(&mut img, &m.corners, label_colour, true);
        let top = m.corners.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
        let left = m.corners.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
        if top.is_finite() && left.is_finite() {
            draw_text_mut(
                &mut img,
                label_colour,
                left as i32,
                top as i32 - 15,
                13.0,
                &font,
                &format!("{}/{}", m.robot, m.face),
            );
        }
    }
    Ok(img)
}

/// Height of one caption line under a tile of a [`contact_sheet`], pixels.
pub const CAPTION_LINE: u32 = 20;

/// Font size of the captions, pixels (readable at 100 % zoom).
pub const CAPTION_SIZE: f32 = 16.0;

/// Frames side by side, `cols` to a row, each scaled by `scale` (0 < scale <= 1) and with its
/// caption (time, what was read, the track; lines separated by `\n`) written under it in
/// black on white at [`CAPTION_SIZE`] pixels, so that the sheet can be read at 100 % zoom
/// even where the labels drawn inside the scaled frames are small. The caption bar is as
/// tall as the longest caption. `None` when there are no frames; all frames take the first
/// one's size.
///
/// # Errors
/// [`AnnotateError::Font`] if the embedded font does not load.
pub fn contact_sheet(
    frames: &[(RgbImage, String)],
    cols: u32,
    scale: f64,
) -> Result<Option<RgbImage>, AnnotateError> {
    let font = FontRef::try_from_slice(FONT_BYTES).map_err(|_| AnnotateError::Font)?;
    let Some((first, _)) = frames.first() else {
        return Ok(None);
    };
    let scale = if scale.is_finite() {
        scale.clamp(0.05, 1.0)
    } else {
        1.0
    };
    let w = ((f64::from(first.width()) * scale).round() as u32).max(1);
    let h = ((f64::from(first.height()) * scale).round() as u32).max(1);
    let cols = cols.max(1);
    let rows = (frames.len() as u32).div_ceil(cols);
    let lines = frames
        .iter()
        .map(|(_, c)| c.lines().count() as u32)
        .max()
        .unwrap_or(0);
    let tile_h = h + lines * CAPTION_LINE + 4;
    let mut sheet = RgbImage::from_pixel(w * cols, tile_h * rows, Rgb([255, 255, 255]));
    for (i, (frame, caption)) in frames.iter().enumerate() {
        let small = image::imageops::resize(frame, w, h, image::imageops::FilterType::Triangle);
        let (x, y) = ((i as u32 % cols) * w, (i as u32 / cols) * tile_h);
        image::imageops::overlay(&mut sheet, &small, i64::from(x), i64::from(y));
        for (k, line) in caption.lines().enumerate() {
            draw_text_mut(
                &mut sheet,
                Rgb([0, 0, 0]),
                x as i32 + 6,
                (y + h + 2 + k as u32 * CAPTION_LINE) as i32,
                CAPTION_SIZE,
                &font,
                line,
            );
        }
    }
    Ok(Some(sheet))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether any pixel of the rectangle is dark (text drawn there).
    fn has_ink(img: &RgbImage, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        (y0..y1).any(|y| (x0..x1).any(|x| img.get_pixel(x, y).0[0] < 100))
    }

    #[test]
    fn contact_sheet_captions_each_tile_below_its_frame() {
        let frame = RgbImage::from_pixel(200, 100, Rgb([200, 200, 200]));
        let frames = vec![
            (frame.clone(), "t = 0.00 s   read 1/3\ntracking".to_owned()),
            (frame.clone(), "t = 1.00 s".to_owned()),
            (frame, String::new()),
        ];
        let sheet = contact_sheet(&frames, 2, 0.5).unwrap().unwrap();
        // Tiles of 100 x 50 with a two-line caption bar, two tiles to a row, two rows.
        let tile_h = 50 + 2 * CAPTION_LINE + 4;
        assert_eq!(sheet.dimensions(), (200, 2 * tile_h));
        // Both lines of the first caption, the second tile's one line, nothing for the third.
        assert!(has_ink(&sheet, 0, 50, 100, 50 + CAPTION_LINE));
        assert!(has_ink(&sheet, 0, 50 + CAPTION_LINE, 100, tile_h));
        assert!(has_ink(&sheet, 100, 50, 200, 50 + CAPTION_LINE));
        assert!(!has_ink(&sheet, 100, 50 + CAPTION_LINE, 200, tile_h));
        assert!(!has_ink(&sheet, 0, tile_h + 50, 100, 2 * tile_h));
        // The frames themselves are untouched by the captions.
        assert!(!has_ink(&sheet, 0, 0, 200, 50));
        assert!(contact_sheet(&[], 3, 0.5).unwrap().is_none());
    }
}
