//! Borrowed 8-bit grey images: the one pixel type every stage of the detector reads.
//!
//! The detector never owns the caller's frame; it reads rows through a [`GrayView`]. A view
//! has a `stride` (bytes from one row to the next) so that a sub-rectangle or a padded frame
//! buffer can be read without copying. Coordinates follow the pixel-centre convention of the
//! spec (section 2.1): integer coordinates are pixel centres, so the image covers
//! `[-0.5, width - 0.5] x [-0.5, height - 0.5]`.

use thiserror::Error;

/// Corner order of a marker, in its own frame: north-west, north-east, south-east,
/// south-west (clockwise in the image, whose v axis points down).
pub type Corners = [nalgebra::Point2<f64>; 4];

/// Why a buffer cannot be viewed as a grey image.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ImageError {
    /// Width or height is zero.
    #[error("image is empty ({width}x{height}); a frame needs at least one pixel")]
    Empty {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The stride is shorter than a row.
    #[error("stride {stride} is shorter than the row width {width}")]
    StrideTooSmall {
        /// Bytes per row requested.
        stride: usize,
        /// Width in pixels.
        width: usize,
    },
    /// The buffer does not hold `height` rows of `stride` bytes (the last row needs only
    /// `width` bytes).
    #[error("buffer of {len} bytes is too short for {width}x{height} with stride {stride}")]
    BufferTooShort {
        /// Length of the buffer.
        len: usize,
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Bytes per row.
        stride: usize,
    },
    /// The image is larger than the detector accepts (see [`GrayView::MAX_SIDE`]).
    #[error("image {width}x{height} is larger than the {max}x{max} the detector accepts")]
    TooLarge {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Largest side accepted.
        max: usize,
    },
}

/// A borrowed, row-major, 8-bit grey image.
#[derive(Debug, Clone, Copy)]
pub struct GrayView<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a> GrayView<'a> {
    /// Largest width or height accepted (keeps every index inside `u32` and every buffer
    /// size sane; 16384 covers any real camera).
    pub const MAX_SIDE: usize = 16_384;

    /// Views a tightly packed buffer (`stride == width`).
    pub fn new(data: &'a [u8], width: usize, height: usize) -> Result<Self, ImageError> {
        Self::with_stride(data, width, height, width)
    }

    /// Views a buffer whose rows are `stride` bytes apart.
    pub fn with_stride(
        data: &'a [u8],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, ImageError> {
        if width == 0 || height == 0 {
            return Err(ImageError::Empty { width, height });
        }
        if width > Self::MAX_SIDE || height > Self::MAX_SIDE {
            return Err(ImageError::TooLarge {
                width,
                height,
                max: Self::MAX_SIDE,
            });
        }
        if stride < width {
            return Err(ImageError::StrideTooSmall { stride, width });
        }
        let needed = stride * (height - 1) + width;
        if data.len() < needed {
            return Err(ImageError::BufferTooShort {
                len: data.len(),
                width,
                height,
                stride,
            });
        }
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// The largest pixel-centre x, `width - 1`, as a float (sides are at most
    /// [`Self::MAX_SIDE`], so through `u32`, whose conversion is one instruction).
    #[inline]
    pub(crate) fn max_x(&self) -> f64 {
        f64::from((self.width - 1) as u32)
    }

    /// The largest pixel-centre y, `height - 1`, as a float (as [`Self::max_x`]).
    #[inline]
    pub(crate) fn max_y(&self) -> f64 {
        f64::from((self.height - 1) as u32)
    }

    /// Whether `(x, y)` lies in `[0, width - 1) x [0, height - 1)`: its 2 x 2 bilinear
    /// square ([`GrayView::square`]) is inside the image, with no clamping (false for NaN).
    #[inline]
    pub(crate) fn within(&self, x: f64, y: f64) -> bool {
        x >= 0.0 && y >= 0.0 && x < self.max_x() && y < self.max_y()
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes from one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Pixels `(x, y)`, `(x + 1, y)`, `(x, y + 1)` and `(x + 1, y + 1)`: the four a bilinear
    /// sample in that square reads. Panics unless `x + 1 < width` and `y + 1 < height`,
    /// which callers inside the crate check first.
    #[inline]
    pub(crate) fn square(&self, x: usize, y: usize) -> [u8; 4] {
        let i = y * self.stride + x;
        let (top, bottom) = (&self.data[i..i + 2], &self.data[i + self.stride..][..2]);
        [top[0], top[1], bottom[0], bottom[1]]
    }

    /// Row `y` (exactly `width` bytes). Panics if `y >= height`, which callers inside the
    /// crate never ask for.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = y * self.stride;
        &self.data[start..start + self.width]
    }

    /// The part of this image inside `region` (cut to the image), as a view of the same
    /// buffer with the same stride: no copy. `None` if the region lies wholly outside.
    /// Pixel `(x, y)` of the result is pixel `(x + r.x, y + r.y)` of this image, where `r`
    /// is the region after cutting.
    pub fn crop(&self, region: crate::roi::Region) -> Option<GrayView<'a>> {
        let r = region.clamped(self.width, self.height)?;
        let start = r.y * self.stride + r.x;
        Some(Self {
            data: &self.data[start..],
            width: r.width,
            height: r.height,
            stride: self.stride,
        })
    }

    /// The pixel at integer coordinates, or `None` outside the image.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<u8> {
        (x < self.width && y < self.height).then(|| self.data[y * self.stride + x])
    }
}

/// The mean of each `f x f` block of `img` (`f` from 1 to 4, clamped) into `out` (`width / f`
/// by `height / f`, row major; the last partial block of a row or column is dropped), each
/// mean rounded half up. One pass over the rows, with the block size a compile-time
/// constant so the inner sums unroll (the coarse scan of a search at a coarser scale,
/// [`crate::Search::scale`], whole frame or regions).
pub(crate) fn decimate(img: &GrayView<'_>, f: usize, out: &mut Vec<u8>) {
    match f.clamp(1, 4) {
        1 => decimate_by::<1>(img, out),
        2 => decimate_by::<2>(img, out),
        3 => decimate_by::<3>(img, out),
        _ => decimate_by::<4>(img, out),
    }
}

fn decimate_by<const F: usize>(img: &GrayView<'_>, out: &mut Vec<u8>) {
    let (w, h) = (img.width() / F, img.height() / F);
    // Every byte is written below: resize only.
    out.resize(w * h, 0);
    if w == 0 {
        return;
    }
    let n = (F * F) as u32;
    for (y, orow) in out.chunks_exact_mut(w).enumerate() {
        let rows: [&[u8]; F] = std::array::from_fn(|k| &img.row(F * y + k)[..F * w]);
        for (x, o) in orow.iter_mut().enumerate() {
            let mut s = 0u32;
            for r in &rows {
                for &v in &r[F * x..F * x + F] {
                    s += u32::from(v);
                }
            }
            *o = ((s + n / 2) / n) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #[test]
        fn decimate_is_the_rounded_block_mean(
            w in 1usize..30,
            h in 1usize..20,
            pad in 0usize..3,
            f in 1usize..5,
            seed in proptest::prelude::any::<u64>(),
        ) {
            // A strided view, so that rows are read through the stride.
            let stride = w + pad;
            let data = crate::test_bytes(seed, stride * h, |_, state| {
                state as u8
            });
            let img = GrayView::with_stride(&data, w, h, stride).unwrap();
            let mut out = vec![7u8; 1000];
            decimate(&img, f, &mut out);
            let (sw, sh) = (w / f, h / f);
            proptest::prop_assert_eq!(out.len(), sw * sh);
            for y in 0..sh {
                for x in 0..sw {
                    let s: u32 = (0..f * f)
                        .map(|k| u32::from(data[(f * y + k / f) * stride + f * x + k % f]))
                        .sum();
                    let n = (f * f) as u32;
                    proptest::prop_assert_eq!(u32::from(out[y * sw + x]), (s + n / 2) / n);
                }
            }
        }
    }

    #[test]
    fn rejects_bad_shapes() {
        let buf = [0u8; 12];
        assert!(matches!(
            GrayView::new(&buf, 0, 3),
            Err(ImageError::Empty { .. })
        ));
        assert!(matches!(
            GrayView::new(&buf, 4, 4),
            Err(ImageError::BufferTooShort { .. })
        ));
        assert!(matches!(
            GrayView::with_stride(&buf, 4, 2, 3),
            Err(ImageError::StrideTooSmall { .. })
        ));
        assert!(matches!(
            GrayView::new(&buf, 20_000, 1),
            Err(ImageError::TooLarge { .. })
        ));
    }

    #[test]
    fn strided_rows() {
        let buf: Vec<u8> = (0..11).collect();
        let v = GrayView::with_stride(&buf, 3, 3, 4).unwrap();
        assert_eq!(v.row(0), &[0, 1, 2]);
        assert_eq!(v.row(2), &[8, 9, 10]);
        assert_eq!(v.get(2, 1), Some(6));
        assert_eq!(v.get(3, 1), None);
    }

    #[test]
    fn crops_share_the_buffer() {
        let buf: Vec<u8> = (0..20).collect();
        let v = GrayView::new(&buf, 5, 4).unwrap();
        let c = v.crop(crate::roi::Region::new(3, 1, 10, 2)).unwrap();
        assert_eq!((c.width(), c.height(), c.stride()), (2, 2, 5));
        assert_eq!(c.row(0), &[8, 9]);
        assert_eq!(c.row(1), &[13, 14]);
        assert!(v.crop(crate::roi::Region::new(5, 0, 1, 1)).is_none());
    }
}
