//! Quads from clusters of the light/dark boundary, AprilTag 3's way: the last look at a
//! large dark component that gave no quadrilateral, after the re-cut of [`crate::split`]
//! (issue #13, real frames).
//!
//! A marker lying almost flat, seen at a grazing angle, may touch something as dark as its
//! ink on its far side: its white margin is a pixel or less tall and the first binary image
//! (smoothed, 8 px tiles, 8-connected dark components) joins its black border to the dark
//! object beyond, so no closed dark component has the marker's outline. AprilTag 3 finds
//! such markers because it never asks for one: it labels the dark *and* the light pixels
//! into components (dark 4-connected, light 8-connected, so a one-pixel light line, even a
//! diagonal one, cuts two dark areas apart) and groups the boundary pixels by the pair of
//! components they separate. The black border of a marker and the light card around it are
//! one such pair, whatever touches the card elsewhere.
//!
//! Here that is done inside the box of each component that gave no quad (widened by a few
//! pixels so that the light surround is in it), on the grey image as it is (no smoothing:
//! it is what blurs the thin margin away) with AprilTag's threshold: the midpoint of the
//! minimum and maximum over 3 x 3 tiles of 4 px, pixels of neighbourhoods flatter than a
//! minimum contrast left unlabelled. The dark pixels of each boundary cluster, ordered by
//! their angle about the cluster's centroid, are a closed outline, and the quad fit, the
//! refinement on the grey image and the decoding are the same as for every other quad,
//! with looser size and angle limits ([`MIN_SIDE_REL`], [`MIN_ANGLE_DEG`]: the markers this
//! path is for are seen at grazing angles); a cluster that is not a marker's outline is
//! rejected by the fit's straightness and angle limits or, at the latest, by the decoder.
//!
//! Cost: nothing on a frame in which every large dark component was a quadrilateral (the
//! synthetic marker scenes); on a cluttered frame one labelling of the re-cut boxes, in
//! time linear in their area, plus a sort of the boundary pixels.

use crate::image::{Corners, GrayView};
use crate::quad::{QuadLimits, fit_quad};
use crate::split::{Rect, SplitParams};

/// Tile side of the threshold, pixels (AprilTag 3's 4; the neighbourhood is 3 x 3 tiles).
const TILE: usize = 4;

/// Neighbourhoods whose max - min grey level is below this are left unlabelled.
const MIN_CONTRAST: u8 = 20;

/// The box of a component is widened by this many pixels on every side.
const PAD: u32 = 4;

/// Shortest side of a cluster's quadrilateral, as a fraction of the detector's `min_side`
/// (the longer extent of the cluster must still reach `min_side`): a marker seen at a
/// grazing angle is foreshortened to half its width or less (Duckietown tag 198 of
/// `test_image_multiple_01.png`: 20 x 10 px).
pub const MIN_SIDE_REL: f64 = 0.5;

/// Smallest interior angle of a cluster's quadrilateral, degrees (the detector's
/// `min_angle_deg` when that is smaller): a marker almost flat on the table and seen along
/// its diagonal has two sharp corners (Duckietown tag 58 of `test_image_multiple_09.png`:
/// 29.4 degrees in AprilTag 3's corners). The first pass's default is the same since
/// 2026-12-07 ([`crate::DetectorConfig::min_angle_deg`]); this bound keeps clustering
/// reading such markers under a stricter first pass. AprilTag 3 accepts down to 10 degrees.
pub const MIN_ANGLE_DEG: f64 = 15.0;

/// Pixel classes.
const DARK: u8 = 0;
const LIGHT: u8 = 1;
const UNKNOWN: u8 = 2;

/// Scratch buffers of the boundary clustering, reused from frame to frame.
#[derive(Debug, Default, Clone)]
pub struct Clusterer {
    class: Vec<u8>,
    parent: Vec<u32>,
    size: Vec<u32>,
    /// Grey-level extremes of the box's tiles.
    tiles: crate::split::BoxTiles,
    /// (cluster key, pixel index in the box) of every dark boundary pixel.
    edges: Vec<(u64, u32)>,
    contour: Vec<[i32; 2]>,
    angles: Vec<(f64, [i32; 2])>,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

fn union(parent: &mut [u32], size: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra == rb {
        return;
    }
    let (big, small) = if size[ra as usize] >= size[rb as usize] {
        (ra, rb)
    } else {
        (rb, ra)
    };
    parent[small as usize] = big;
    size[big as usize] += size[small as usize];
}

impl Clusterer {
    /// Clusters the light/dark boundary of `img` inside `rect` (widened by a few pixels) and
    /// calls `found` with the coarse corners (image pixel coordinates, clockwise in the
    /// image) of each cluster that is a quadrilateral; the caller refines those it does not
    /// know yet.
    pub fn clusters(
        &mut self,
        img: &GrayView<'_>,
        rect: Rect,
        params: &SplitParams<'_>,
        mut found: impl FnMut(Corners),
    ) {
        let (w, h) = (img.width(), img.height());
        if w == 0 || h == 0 {
            return;
        }
        let x0 = rect.x0.saturating_sub(PAD) as usize;
        let y0 = rect.y0.saturating_sub(PAD) as usize;
        let x1 = (rect.x1.saturating_add(PAD) as usize).min(w - 1);
        let y1 = (rect.y1.saturating_add(PAD) as usize).min(h - 1);
        if x1 < x0 + 2 || y1 < y0 + 2 {
            return;
        }
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let n = cw * ch;
        if u32::try_from(n).is_err() {
            return;
        }
        self.threshold(img, x0, y0, cw, ch);
        self.label(cw, ch);
        let min_side = params.min_side.max(3) as usize;
        // Components too small to be a marker's border or margin give no cluster.
        let min_pixels = min_side as u32;
        let Self {
            class,
            parent,
            size,
            edges,
            contour,
            angles,
            ..
        } = self;
        edges.clear();
        for y in 0..ch {
            for x in 0..cw {
                let i = y * cw + x;
                if class[i] != DARK {
                    continue;
                }
                let rd = find(parent, i as u32);
                if size[rd as usize] < min_pixels {
                    continue;
                }
                let mut seen = [u32::MAX; 4];
                let neighbours = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < cw).then(|| i + 1),
                    (y > 0).then(|| i - cw),
                    (y + 1 < ch).then(|| i + cw),
                ];
                for (k, j) in neighbours.into_iter().enumerate() {
                    let Some(j) = j else { continue };
                    if class[j] != LIGHT {
                        continue;
                    }
                    let rl = find(parent, j as u32);
                    if size[rl as usize] < min_pixels || seen.contains(&rl) {
                        continue;
                    }
                    seen[k] = rl;
                    edges.push(((u64::from(rd) << 32) | u64::from(rl), i as u32));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let m = params.border_margin.max(1) as usize;
        let limits = QuadLimits {
            min_side: MIN_SIDE_REL * params.limits.min_side,
            min_angle_deg: params.limits.min_angle_deg.min(MIN_ANGLE_DEG),
            ..*params.limits
        };
        let mut start = 0;
        while start < edges.len() {
            let key = edges[start].0;
            let end = start + edges[start..].iter().take_while(|e| e.0 == key).count();
            let run = &edges[start..end];
            start = end;
            // A marker's outline: at least its four shortest sides, at most the box's
            // perimeter twice over.
            if run.len() < 2 * min_side || run.len() > 4 * (cw + ch) {
                continue;
            }
            let (mut bx0, mut by0, mut bx1, mut by1) = (usize::MAX, usize::MAX, 0, 0);
            let (mut sx, mut sy) = (0.0, 0.0);
            for &(_, i) in run {
                let (x, y) = (i as usize % cw, i as usize / cw);
                (bx0, by0, bx1, by1) = (bx0.min(x), by0.min(y), bx1.max(x), by1.max(y));
                sx += x as f64;
                sy += y as f64;
            }
            let (bw, bh) = (bx1 - bx0 + 1, by1 - by0 + 1);
            if bw.max(bh) < min_side
                || bw.min(bh) < min_side / 2
                || x0 + bx0 < m
                || y0 + by0 < m
                || x0 + bx1 + m >= w
                || y0 + by1 + m >= h
            {
                continue;
            }
            let (cx, cy) = (sx / run.len() as f64, sy / run.len() as f64);
            angles.clear();
            angles.extend(run.iter().map(|&(_, i)| {
                let (x, y) = (i as usize % cw, i as usize / cw);
                (
                    (y as f64 - cy).atan2(x as f64 - cx),
                    [(x0 + x) as i32, (y0 + y) as i32],
                )
            }));
            angles.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            contour.clear();
            contour.extend(angles.iter().map(|a| a.1));
            if let Some(coarse) = fit_quad(contour, &limits) {
                found(coarse);
            }
        }
    }

    /// AprilTag's threshold of the box at `(x0, y0)`, `cw x ch`, into `self.class`.
    fn threshold(&mut self, img: &GrayView<'_>, x0: usize, y0: usize, cw: usize, ch: usize) {
        let (tw, th) = self.tiles.compute(img, x0, y0, cw, ch, TILE);
        self.class.clear();
        self.class.resize(cw * ch, UNKNOWN);
        for ty in 0..th {
            for tx in 0..tw {
                let (lo, hi) = self.tiles.around(tx, ty);
                if hi.saturating_sub(lo) < MIN_CONTRAST {
                    continue;
                }
                let cut = u16::from(lo) + u16::from(hi - lo) / 2;
                for y in ty * TILE..((ty + 1) * TILE).min(ch) {
                    let row = &img.row(y0 + y)[x0..x0 + cw];
                    let (xa, xb) = (tx * TILE, ((tx + 1) * TILE).min(cw));
                    let class = &mut self.class[y * cw + xa..y * cw + xb];
                    for (c, &v) in class.iter_mut().zip(&row[xa..xb]) {
                        *c = if u16::from(v) > cut { LIGHT } else { DARK };
                    }
                }
            }
        }
    }

    /// Union-find of the classes: dark pixels 4-connected, light ones 8-connected.
    fn label(&mut self, cw: usize, ch: usize) {
        let n = cw * ch;
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.size.clear();
        self.size.resize(n, 1);
        let (class, parent, size) = (&self.class, &mut self.parent, &mut self.size);
        for y in 0..ch {
            for x in 0..cw {
                let i = y * cw + x;
                let c = class[i];
                if c == UNKNOWN {
                    continue;
                }
                if x + 1 < cw && class[i + 1] == c {
                    union(parent, size, i as u32, (i + 1) as u32);
                }
                if y + 1 < ch {
                    if class[i + cw] == c {
                        union(parent, size, i as u32, (i + cw) as u32);
                    }
                    if c == LIGHT {
                        if x + 1 < cw && class[i + cw + 1] == c {
                            union(parent, size, i as u32, (i + cw + 1) as u32);
                        }
                        if x > 0 && class[i + cw - 1] == c {
                            union(parent, size, i as u32, (i + cw - 1) as u32);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const LIMITS: QuadLimits = QuadLimits {
        min_side: 10.0,
        min_angle_deg: 30.0,
        line_tolerance: 1.5,
        line_tolerance_rel: 0.05,
    };

    fn quads_in(px: &[u8], w: usize, rect: Rect) -> Vec<Corners> {
        let img = GrayView::new(px, w, px.len() / w).unwrap();
        let params = SplitParams {
            limits: &LIMITS,
            border_margin: 2,
            min_side: 10,
        };
        let mut found = Vec::new();
        Clusterer::default().clusters(&img, rect, &params, |q| found.push(q));
        found
    }

    /// A dark square whose lower side is one light pixel row away from a dark block: the
    /// 8-connected, smoothed first pass sees one component; the clusters see the square.
    #[test]
    fn square_next_to_a_dark_block_is_its_own_cluster() {
        let w = 60;
        let mut px = vec![200u8; w * 60];
        for y in 0..60 {
            for x in 0..w {
                let square = (20..40).contains(&x) && (20..40).contains(&y);
                let block = (10..50).contains(&x) && (41..55).contains(&y);
                if square || block {
                    px[y * w + x] = 30;
                }
            }
        }
        let rect = Rect {
            x0: 10,
            y0: 20,
            x1: 49,
            y1: 54,
        };
        let found = quads_in(&px, w, rect);
        let want = [[20.0, 20.0], [39.0, 20.0], [39.0, 39.0], [20.0, 39.0]];
        assert!(
            found.iter().any(|q| want
                .iter()
                .all(|c| q.iter().any(|p| (p[0] - c[0]).hypot(p[1] - c[1]) < 1.0))),
            "{found:?}"
        );
    }

    proptest! {
        /// Any frame and any box: no panic, and every corner handed back is finite and
        /// inside the frame.
        #[test]
        fn any_frame_any_box(
            px in proptest::collection::vec(any::<u8>(), 24 * 20),
            x0 in 0u32..40, y0 in 0u32..40, dx in 0u32..40, dy in 0u32..40,
        ) {
            let rect = Rect { x0, y0, x1: x0 + dx, y1: y0 + dy };
            for q in quads_in(&px, 24, rect) {
                for (x, y) in q.map(|p| (p.x, p.y)) {
                    prop_assert!(x.is_finite() && y.is_finite());
                    prop_assert!((-1.0..25.0).contains(&x) && (-1.0..21.0).contains(&y));
                }
            }
        }
    }
}
