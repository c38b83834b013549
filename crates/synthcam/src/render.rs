//! Render settings, the output frame, and the parallel render loop.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::camera::PosedCamera;
use crate::error::{SynthError, finite, finite_vec, in_range};
use crate::raycast::{Light, Prepared};
use crate::scene::Scene;
use crate::truth::{FrameTruth, ground_truth, ground_truth_prepared};

/// Largest supersampling factor (samples per pixel side).
pub const MAX_SUPERSAMPLING: usize = 32;

/// A linear brightness gradient across the image: the light factor goes from `from` on one side
/// of the image to `to` on the opposite side, along the image direction `angle` (radians;
/// 0 = left to right, pi/2 = top to bottom).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gradient {
    /// Factor at the start side.
    pub from: f64,
    /// Factor at the end side.
    pub to: f64,
    /// Direction in the image (rad, 0 = +u, pi/2 = +v).
    pub angle: f64,
}

/// Diffuse shading of bodies and the ground (and optionally of the rig faces).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// Direction *towards* the light, world frame (any non-zero length).
    pub light_dir: Vector3<f64>,
    /// Ambient fraction in `[0, 1]`: a surface facing away from the light gets this factor,
    /// one facing it gets 1.
    pub ambient: f64,
    /// Shade rig faces too. Off by default so marker faces stay crisp and uniform.
    pub shade_faces: bool,
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            light_dir: Vector3::new(0.4, 0.3, 1.0),
            ambient: 0.55,
            shade_faces: false,
        }
    }
}

/// Output pixel format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PixelFormat {
    /// One byte per pixel.
    #[default]
    Grey,
    /// Three bytes per pixel (R, G, B); the grey image in each channel, with independent noise.
    Rgb,
}

/// Everything about how a frame is rendered, apart from the scene and camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Samples per pixel side: `n x n` stratified samples over the pixel's area (a box
    /// filter), one in each cell of an `n x n` grid, placed so that no two share a column or
    /// a row of an `n^2 x n^2` grid (the canonical "multi-jittered" arrangement, without the
    /// jitter: sample `(i, j)` sits at `((i + (j + 1/2) / n) / n, (j + (i + 1/2) / n) / n)`
    /// in the pixel). An edge along a pixel axis, the common case for a level camera's
    /// vertical marker edges, then lands within `1 / (2 n^2)` px of its true place instead of
    /// the `1 / (2 n)` px of the plain grid of cell centres. `2` means 4 samples per pixel.
    pub supersampling: usize,
    /// Overall light gain: an albedo of 1 renders as `255 * gain` before clamping.
    pub gain: f64,
    /// Optional brightness gradient across the image.
    pub gradient: Option<Gradient>,
    /// Optional diffuse shading (`None`: every surface shows its raw albedo).
    pub shading: Option<Shading>,
    /// Standard deviation of the optical Gaussian blur, in pixels (0: none).
    pub blur_sigma: f64,
    /// Standard deviation of additive Gaussian sensor noise, in grey levels (0: none).
    pub noise_sigma: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Output format.
    pub format: PixelFormat,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            supersampling: 2,
            gain: 1.0,
            gradient: None,
            shading: Some(Shading::default()),
            blur_sigma: 0.0,
            noise_sigma: 0.0,
            seed: 0,
            format: PixelFormat::Grey,
        }
    }
}

impl RenderSettings {
    /// Check every setting.
    pub fn validate(&self) -> Result<(), SynthError> {
        if self.supersampling == 0 || self.supersampling > MAX_SUPERSAMPLING {
            return Err(SynthError::InvalidSupersampling {
                n: self.supersampling,
                max: MAX_SUPERSAMPLING,
            });
        }
        in_range("gain", self.gain, 0.0, 1e6)?;
        if let Some(g) = &self.gradient {
            in_range("gradient from", g.from, 0.0, 1e6)?;
            in_range("gradient to", g.to, 0.0, 1e6)?;
            finite("gradient angle", g.angle)?;
        }
        if let Some(s) = &self.shading {
            finite_vec("light direction", &s.light_dir)?;
            if s.light_dir.norm() == 0.0 {
                return Err(SynthError::DegenerateGeometry {
                    what: "light direction is zero",
                });
            }
            in_range("ambient", s.ambient, 0.0, 1.0)?;
        }
        for (what, v) in [
            ("blur sigma", self.blur_sigma),
            ("noise sigma", self.noise_sigma),
        ] {
            finite(what, v)?;
            if v < 0.0 {
                return Err(SynthError::NegativeSigma { what, value: v });
            }
        }
        in_range("blur sigma", self.blur_sigma, 0.0, 100.0)?;
        Ok(())
    }
}

/// An 8-bit image: `data` is row-major, `channels()` bytes per pixel, no padding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixel format.
    pub format: PixelFormat,
    /// Pixel bytes.
    pub data: Vec<u8>,
}

impl Frame {
    /// Bytes per pixel.
    pub fn channels(&self) -> usize {
        match self.format {
            PixelFormat::Grey => 1,
            PixelFormat::Rgb => 3,
        }
    }

    /// The grey level at `(u, v)` (for RGB, the mean of the channels); `None` outside.
    pub fn grey(&self, u: usize, v: usize) -> Option<u8> {
        if u >= self.width || v >= self.height {
            return None;
        }
        let c = self.channels();
        let i = (v * self.width + u) * c;
        let px = self.data.get(i..i + c)?;
        Some((px.iter().map(|&b| u32::from(b)).sum::<u32>() / c as u32) as u8)
    }

    /// Write the frame as binary PGM (grey) or PPM (RGB).
    pub fn write_pnm<W: std::io::Write>(&self, mut w: W) -> Result<(), SynthError> {
        let magic = match self.format {
            PixelFormat::Grey => "P5",
            PixelFormat::Rgb => "P6",
        };
        write!(w, "{magic}\n{} {}\n255\n", self.width, self.height)?;
        w.write_all(&self.data)?;
        Ok(())
    }
}

/// A rendered frame and its exact ground truth.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The image.
    pub frame: Frame,
    /// The ground truth of the scene as seen by the camera.
    pub truth: FrameTruth,
}

/// Render `scene` through `camera` and compute the ground truth.
///
/// Validates everything first: any bad input is a typed error, never a panic or a NaN pixel.
pub fn render(
    scene: &Scene,
    camera: &PosedCamera,
    settings: &RenderSettings,
) -> Result<Rendered, SynthError> {
    render_with_progress(scene, camera, settings, &|_, _| {})
}

/// As [`render`], calling `progress(rows_done, rows)` each time a row of the image has been
/// traced (from the worker threads, in no particular order; `rows_done` only grows), so that
/// a caller can show how far a large frame has come. Tracing is nearly all of the time; the
/// blur and quantisation after the last call are quick.
///
/// # Errors
/// As [`render`].
pub fn render_with_progress(
    scene: &Scene,
    camera: &PosedCamera,
    settings: &RenderSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Rendered, SynthError> {
    scene.validate()?;
    settings.validate()?;
    let light = settings.shading.map(|s| Light {
        dir: s.light_dir.normalize(),
        ambient: s.ambient,
        shade_faces: s.shade_faces,
    });
    let prepared = Prepared::new(scene, camera, light.as_ref())?;
    let truth = ground_truth_prepared(scene, camera, &prepared)?;
    let mut radiance = trace_image(&prepared, camera, settings, progress);
    let (w, h) = (camera.width(), camera.height());
    if settings.blur_sigma > 0.0 {
        gaussian_blur(&mut radiance, w, h, settings.blur_sigma);
    }
    let frame = quantise(&radiance, w, h, settings);
    Ok(Rendered { frame, truth })
}

/// Renders one frame exposed over a time interval: motion blur. `views` are the scene and
/// camera at instants spread evenly over the exposure, in time order (e.g. the robots'
/// poses at `n` sub-frame times); their radiances are averaged *before* the optical blur and
/// the sensor noise, as a sensor integrates light over its exposure, so the noise is that
/// of one frame. The ground truth is that of the middle view (`views[views.len() / 2]`):
/// with an odd count spread symmetrically about the frame time, the truth at that time.
/// One view is exactly [`render`].
///
/// # Errors
/// As [`render`]; [`SynthError::InvalidExposure`] when `views` is empty or the views'
/// cameras differ in size.
pub fn render_exposure(
    views: &[(&Scene, &PosedCamera)],
    settings: &RenderSettings,
) -> Result<Rendered, SynthError> {
    settings.validate()?;
    let Some(&(mid_scene, mid_camera)) = views.get(views.len() / 2) else {
        return Err(SynthError::InvalidExposure {
            reason: "no sub-frame to expose",
        });
    };
    let (w, h) = (mid_camera.width(), mid_camera.height());
    if views.iter().any(|(_, c)| c.width() != w || c.height() != h) {
        return Err(SynthError::InvalidExposure {
            reason: "the sub-frames' cameras differ in size",
        });
    }
    let light = settings.shading.map(|s| Light {
        dir: s.light_dir.normalize(),
        ambient: s.ambient,
        shade_faces: s.shade_faces,
    });
    let mut sum = vec![0f32; w * h];
    let mut truth = None;
    for (i, &(scene, camera)) in views.iter().enumerate() {
        scene.validate()?;
        let prepared = Prepared::new(scene, camera, light.as_ref())?;
        if i == views.len() / 2 {
            truth = Some(ground_truth_prepared(scene, camera, &prepared)?);
        }
        let radiance = trace_image(&prepared, camera, settings, &|_, _| {});
        for (s, r) in sum.iter_mut().zip(&radiance) {
            *s += r;
        }
    }
    let scale = 1.0 / views.len() as f32;
    sum.iter_mut().for_each(|x| *x *= scale);
    if settings.blur_sigma > 0.0 {
        gaussian_blur(&mut sum, w, h, settings.blur_sigma);
    }
    let frame = quantise(&sum, w, h, settings);
    let truth = match truth {
        Some(t) => t,
        None => ground_truth(mid_scene, mid_camera)?,
    };
    Ok(Rendered { frame, truth })
}

/// Light factor across the image (gain times gradient), as `a + b u + c v`.
fn light_plane(settings: &RenderSettings, w: usize, h: usize) -> [f64; 3] {
    match settings.gradient {
        None => [settings.gain, 0.0, 0.0],
        Some(g) => {
            let (sn, cs) = g.angle.sin_cos();
            let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
            let extent = (w as f64 * cs).abs() + (h as f64 * sn).abs();
            // position along the direction, 0 at the start side and 1 at the end side.
            let k = (g.to - g.from) / extent;
            let a = g.from + (g.to - g.from) * 0.5 - k * (cs * cx + sn * cy);
            [
                settings.gain * a,
                settings.gain * k * cs,
                settings.gain * k * sn,
            ]
        }
    }
}

/// Radiance in grey levels (`255 * albedo * light`), row-major `f32`, not clamped.
fn trace_image(
    prepared: &Prepared<'_>,
    camera: &PosedCamera,
    settings: &RenderSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<f32> {
    let (w, h) = (camera.width(), camera.height());
    let rows_done = AtomicUsize::new(0);
    let kinv = *camera.k_inv();
    let (c0, c1, c2) = (
        kinv.column(0).into_owned(),
        kinv.column(1).into_owned(),
        kinv.column(2).into_owned(),
    );
    let n = settings.supersampling;
    let inv_n = 1.0 / n as f64;
    let weight = 255.0 / (n * n) as f32;
    let lp = light_plane(settings, w, h);
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        let vf = v as f64;
        // Objects whose screen box meets this row.
        let cands: Vec<u32> = prepared
            .prims
            .iter()
            .enumerate()
            .filter(|(_, p)| p.bbox.v0 <= vf + 0.5 && p.bbox.v1 >= vf - 0.5)
            .map(|(i, _)| i as u32)
            .collect();
        let mut local: Vec<u32> = Vec::with_capacity(cands.len());
        for (u, px) in row.iter_mut().enumerate() {
            let uf = u as f64;
            local.clear();
            local.extend(cands.iter().copied().filter(|&i| {
                prepared
                    .prims
                    .get(i as usize)
                    .is_some_and(|p| p.bbox.u0 <= uf + 0.5 && p.bbox.u1 >= uf - 0.5)
            }));
            let mut acc = 0f32;
            for j in 0..n {
                for i in 0..n {
                    // Sub-cell (i, j), shifted within it so that every sample has its own
                    // column and its own row at 1 / n^2 spacing (see `RenderSettings`).
                    let us = uf - 0.5 + (i as f64 + (j as f64 + 0.5) * inv_n) * inv_n;
                    let vs = vf - 0.5 + (j as f64 + (i as f64 + 0.5) * inv_n) * inv_n;
                    let d = c0 * us + c1 * vs + c2;
                    acc += prepared
                        .nearest(&d, Some((us, vs)), &local, f64::INFINITY, None)
                        .map_or(prepared.background, |hit| hit.value);
                }
            }
            let light = (lp[0] + lp[1] * uf + lp[2] * vf) as f32;
            *px = acc * weight * light;
        }
        progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1, h);
    });
    out
}

/// Separable Gaussian blur with clamp-to-edge borders.
fn gaussian_blur(img: &mut [f32], w: usize, h: usize, sigma: f64) {
    let r = (3.0 * sigma).ceil() as usize;
    if r == 0 {
        return;
    }
    let mut k: Vec<f32> = (0..=2 * r)
        .map(|i| {
            let x = i as f64 - r as f64;
            (-x * x / (2.0 * sigma * sigma)).exp() as f32
        })
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= sum);
    let ri = r as isize;
    // Horizontal pass.
    let mut tmp = vec![0f32; w * h];
    tmp.par_chunks_mut(w)
        .zip(img.par_chunks(w))
        .for_each(|(dst, src)| {
            for (u, o) in dst.iter_mut().enumerate() {
                let mut acc = 0f32;
                for (i, kv) in k.iter().enumerate() {
                    let x = (u as isize + i as isize - ri).clamp(0, w as isize - 1) as usize;
                    acc += kv * src.get(x).copied().unwrap_or(0.0);
                }
                *o = acc;
            }
        });
    // Vertical pass.
    img.par_chunks_mut(w).enumerate().for_each(|(v, dst)| {
        dst.iter_mut().for_each(|x| *x = 0.0);
        for (i, kv) in k.iter().enumerate() {
            let y = (v as isize + i as isize - ri).clamp(0, h as isize - 1) as usize;
            if let Some(src) = tmp.get(y * w..(y + 1) * w) {
                for (o, s) in dst.iter_mut().zip(src) {
                    *o += kv * s;
                }
            }
        }
    });
}

/// Add noise (seeded per row, so the result does not depend on thread scheduling), round and
/// clamp to bytes.
fn quantise(radiance: &[f32], w: usize, h: usize, settings: &RenderSettings) -> Frame {
    let c = match settings.format {
        PixelFormat::Grey => 1,
        PixelFormat::Rgb => 3,
    };
    let sigma = settings.noise_sigma as f32;
    let mut data = vec![0u8; w * h * c];
    data.par_chunks_mut(w * c)
        .zip(radiance.par_chunks(w))
        .enumerate()
        .for_each(|(v, (dst, src))| {
            let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
            rng.set_stream(v as u64);
            for (px, &x) in dst.chunks_mut(c).zip(src) {
                for b in px {
                    let noise: f32 = if sigma > 0.0 {
                        let z: f32 = StandardNormal.sample(&mut rng);
                        sigma * z
                    } else {
                        0.0
                    };
                    *b = (x + noise).round().clamp(0.0, 255.0) as u8;
                }
            }
        });
    Frame {
        width: w,
        height: h,
        format: settings.format,
        data,
    }
}
