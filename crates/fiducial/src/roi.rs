//! Regions of interest: the rectangles a tracker hands the detector when it knows where the
//! markers will be (tracking-guided detection, `docs/tracking.md`).
//!
//! A [`Region`] is an axis-aligned rectangle of whole pixels. The detector runs every stage
//! on the region alone ([`crate::Search::regions`]), through a strided
//! [`GrayView`](crate::GrayView) of the caller's frame (no copy), and reports corners in the
//! frame's coordinates. A marker must lie wholly inside a region, at least the detector's
//! `border_margin` from its edge, to be found there: the caller gives a margin.
//!
//! Regions that overlap are merged into their bounding rectangle first
//! ([`merge_overlapping`]), so a marker in the overlap of two predictions is searched once.

/// An axis-aligned rectangle of pixels: columns `x..x + width`, rows `y..y + height`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Region {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Region {
    /// The rectangle with top-left pixel `(x, y)` and the given size.
    pub fn new(x: usize, y: usize, width: usize, height: usize) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }

    /// The whole frame.
    pub fn full(width: usize, height: usize) -> Self {
        Self::new(0, 0, width, height)
    }

    /// The pixels covering the continuous box `[x0, x1] x [y0, y1]` (pixel-centre
    /// coordinates, spec 2.1), cut to a `width x height` frame. `None` when the box is empty,
    /// not finite or wholly outside the frame.
    pub fn from_bounds(
        x0: f64,
        y0: f64,
        x1: f64,
        y1: f64,
        width: usize,
        height: usize,
    ) -> Option<Self> {
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return None;
        }
        if x1 < x0 || y1 < y0 || width == 0 || height == 0 {
            return None;
        }
        // Pixel i covers [i - 0.5, i + 0.5].
        let lo = |v: f64, n: usize| (v + 0.5).floor().clamp(0.0, n as f64) as usize;
        let hi = |v: f64, n: usize| ((v + 0.5).ceil().clamp(0.0, n as f64)) as usize;
        let (a, b) = (lo(x0, width), hi(x1, width));
        let (c, d) = (lo(y0, height), hi(y1, height));
        (b > a && d > c).then(|| Self::new(a, c, b - a, d - c))
    }

    /// This region cut to a `width x height` frame, or `None` if nothing of it is inside.
    pub fn clamped(&self, width: usize, height: usize) -> Option<Self> {
        let x1 = self.x.saturating_add(self.width).min(width);
        let y1 = self.y.saturating_add(self.height).min(height);
        (x1 > self.x && y1 > self.y).then(|| Self::new(self.x, self.y, x1 - self.x, y1 - self.y))
    }

    /// The smallest rectangle holding this one whose edges lie on a grid of `step` pixels
    /// from the frame's origin, cut to a `width x height` frame (the frame's own right and
    /// bottom edges count as grid lines). A `step` of 0 or 1 changes nothing.
    pub fn aligned(&self, step: usize, width: usize, height: usize) -> Self {
        if step <= 1 {
            return *self;
        }
        // One axis: the start rounded down, the end up (not past the frame's edge, nor
        // short of the region's own end).
        let grow = |start: usize, len: usize, limit: usize| {
            let end = start.saturating_add(len);
            let up = end.div_ceil(step).saturating_mul(step).min(limit.max(end));
            (start / step * step, up)
        };
        let (x, x1) = grow(self.x, self.width, width);
        let (y, y1) = grow(self.y, self.height, height);
        Self::new(x, y, x1 - x, y1 - y)
    }

    /// Number of pixels.
    pub fn area(&self) -> usize {
        self.width * self.height
    }

    /// Whether the two rectangles share a pixel.
    pub fn intersects(&self, other: &Self) -> bool {
        self.x < other.x + other.width
            && other.x < self.x + self.width
            && self.y < other.y + other.height
            && other.y < self.y + self.height
    }

    /// The smallest rectangle holding both.
    pub fn union(&self, other: &Self) -> Self {
        let x = self.x.min(other.x);
        let y = self.y.min(other.y);
        let x1 = (self.x + self.width).max(other.x + other.width);
        let y1 = (self.y + self.height).max(other.y + other.height);
        Self::new(x, y, x1 - x, y1 - y)
    }
}

/// Replaces every group of overlapping regions by its bounding rectangle, repeatedly, until
/// no two regions overlap; empty regions are dropped. Works in place (no allocation).
pub(crate) fn merge_overlapping(regions: &mut Vec<Region>) {
    regions.retain(|r| r.area() > 0);
    let mut i = 0;
    while i < regions.len() {
        let mut merged = false;
        let mut j = i + 1;
        while j < regions.len() {
            if regions[i].intersects(&regions[j]) {
                regions[i] = regions[i].union(&regions[j]);
                regions.swap_remove(j);
                merged = true;
            } else {
                j += 1;
            }
        }
        // A grown region may now reach one checked before it: start that one again.
        if merged {
            i = 0;
        } else {
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_cover_the_box_and_stay_in_the_frame() {
        let r = Region::from_bounds(9.6, 4.4, 20.2, 7.5, 640, 480).unwrap();
        // Pixel 8 covers [7.5, 8.5]: the box ends on its edge.
        assert_eq!(r, Region::new(10, 4, 11, 4));
        let r = Region::from_bounds(-50.0, -3.0, 700.0, 10.0, 640, 480).unwrap();
        assert_eq!(r, Region::new(0, 0, 640, 11));
        assert_eq!(Region::from_bounds(700.0, 0.0, 800.0, 5.0, 640, 480), None);
        assert_eq!(Region::from_bounds(f64::NAN, 0.0, 8.0, 5.0, 640, 480), None);
        assert_eq!(Region::from_bounds(8.0, 0.0, 2.0, 5.0, 640, 480), None);
    }

    #[test]
    fn clamping_cuts_to_the_frame() {
        assert_eq!(
            Region::new(600, 470, 100, 100).clamped(640, 480),
            Some(Region::new(600, 470, 40, 10))
        );
        assert_eq!(Region::new(640, 0, 10, 10).clamped(640, 480), None);
        assert_eq!(
            Region::new(usize::MAX - 1, 0, 10, 10).clamped(640, 480),
            None
        );
    }

    #[test]
    fn merging_leaves_no_overlap_and_covers_every_input() {
        let input = vec![
            Region::new(0, 0, 10, 10),
            Region::new(50, 50, 10, 10),
            Region::new(8, 8, 10, 10),
            Region::new(17, 17, 40, 5),
            Region::new(100, 100, 0, 5),
        ];
        let mut merged = input.clone();
        merge_overlapping(&mut merged);
        for (i, a) in merged.iter().enumerate() {
            for b in &merged[i + 1..] {
                assert!(!a.intersects(b), "{a:?} overlaps {b:?}");
            }
        }
        for r in input.iter().filter(|r| r.area() > 0) {
            assert!(
                merged.iter().any(|m| m.union(r) == *m),
                "{r:?} is not covered by {merged:?}"
            );
        }
        // The first, third and fourth chain into one; the second stays apart.
        assert_eq!(merged.len(), 2);
    }
}
