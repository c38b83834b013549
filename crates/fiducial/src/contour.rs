//! Connected components of the binary image and the outer contour of each candidate (spec
//! 3.4, step 3).
//!
//! Components are found on runs, not pixels: each row is cut into runs of dark pixels, and a
//! union-find over runs joins runs of consecutive rows that touch (8-connectivity). This costs
//! one pass over the bytes plus work proportional to the number of runs. Per component we keep
//! its pixel count, bounding box and first (top-left) pixel, which is enough to reject most
//! components cheaply (too small, too large, touching the frame border, too sparse) before
//! any contour is traced. Survivors get their outer border traced by Moore-neighbour
//! following from the top-left pixel, clockwise in the image.

use crate::threshold::DARK;

/// Summary of one 8-connected dark component.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Component {
    /// Number of dark pixels.
    pub pixels: u32,
    /// Smallest x of any pixel.
    pub x_min: u32,
    /// Largest x of any pixel.
    pub x_max: u32,
    /// Smallest y of any pixel.
    pub y_min: u32,
    /// Largest y of any pixel.
    pub y_max: u32,
    /// x of the leftmost pixel of the top row (the tracing start).
    pub start_x: u32,
    /// Holes: the light regions it encloses (4-connected, as the light around 8-connected
    /// dark components is), counted as the independent cycles of its runs' adjacency (a
    /// run graph is planar, and each cycle closes around light pixels of its own).
    pub holes: u32,
}

#[derive(Debug, Clone, Copy)]
struct Run {
    y: u32,
    x0: u32,
    /// Exclusive end.
    x1: u32,
}

/// Run-length union-find labelling with reusable buffers.
#[derive(Debug, Default, Clone)]
pub struct Labeller {
    runs: Vec<Run>,
    parent: Vec<u32>,
    /// The component of each run.
    run_component: Vec<u32>,
    /// Per run: its joins to runs of the row above that were in its component already
    /// (each closes a cycle around a hole).
    cycles: Vec<u32>,
    components: Vec<Component>,
    /// The row being added: its y and first run.
    row: Option<(u32, usize)>,
    /// The previous row: its y and runs.
    prev: Option<(u32, usize, usize)>,
}

impl Labeller {
    /// An empty labeller; buffers grow on the first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// Labels the dark components of `bin` (`width` bytes per row) and returns them in the
    /// raster order of their top-left pixel.
    pub fn label(&mut self, bin: &[u8], width: usize) -> &[Component] {
        // The whole image is one band.
        self.label_band(0, bin, width);
        self.gather()
    }

    /// Starts a labelling whose pixels come in pieces of rows ([`Labeller::add_row`]), for
    /// [`Labeller::finish`]: the re-cut labels only the pixels it cut.
    pub(crate) fn begin(&mut self) {
        self.runs.clear();
        self.cycles.clear();
        self.parent.clear();
        self.components.clear();
        self.row = None;
        self.prev = None;
    }

    /// Adds the dark runs of `pixels`, the pixels `x0 ..` of row `y`. Rows come in
    /// increasing order and the pieces of a row from left to right, none touching the next
    /// (a run never continues from one piece into the next); pixels not given are light.
    #[inline]
    pub(crate) fn add_row(&mut self, y: u32, x0: u32, pixels: &[u8]) {
        match self.row {
            Some((ry, _)) if ry == y => {}
            _ => {
                self.end_row();
                self.row = Some((y, self.runs.len()));
            }
        }
        // The row 64 pixels at a time as a bit mask (bit `i` set for a dark pixel), its
        // runs read from the mask's set and clear bits: textured frames have runs of a few
        // pixels, which a byte-by-byte or word-by-word search pays for at every boundary.
        let runs = &mut self.runs;
        let mut start: Option<usize> = None;
        let mut push = |a: usize, b: usize| {
            runs.push(Run {
                y,
                x0: x0 + a as u32,
                x1: x0 + b as u32,
            });
        };
        let mut blocks = pixels.chunks_exact(64);
        let mut base = 0usize;
        for block in blocks.by_ref() {
            let m = dark_mask(block);
            // Nothing starts or ends in a block all light outside a run or all dark in one.
            if (m == 0 && start.is_none()) || (m == u64::MAX && start.is_some()) {
                base += 64;
                continue;
            }
            runs_of_mask(m, 64, base, &mut start, &mut push);
            base += 64;
        }
        let rest = blocks.remainder();
        if !rest.is_empty() {
            runs_of_mask(dark_mask(rest), rest.len(), base, &mut start, &mut push);
        }
        if let Some(a) = start {
            push(a, pixels.len());
        }
    }

    /// Joins the current row's runs with the overlapping runs of the row above it, if that
    /// was the previous row given (8-connectivity: pixel ranges [a0, a1) and [b0, b1) touch
    /// when a0 <= b1 and b0 <= a1); the current row becomes the previous one.
    fn end_row(&mut self) {
        let Some((y, row_start)) = self.row.take() else {
            return;
        };
        let row_end = self.runs.len();
        // The row's runs, each its own component so far, with no cycle yet.
        self.parent.extend(row_start as u32..row_end as u32);
        self.cycles.resize(row_end, 0);
        if let Some((py, prev_start, prev_end)) = self.prev
            && py + 1 == y
        {
            self.join((prev_start, prev_end), (row_start, row_end));
        }
        self.prev = Some((y, row_start, row_end));
    }

    /// Joins the runs `row_start .. row_end` of a row with the overlapping runs
    /// `prev_start .. prev_end` of the row above it.
    fn join(
        &mut self,
        (prev_start, prev_end): (usize, usize),
        (row_start, row_end): (usize, usize),
    ) {
        let mut p = prev_start;
        for r in row_start..row_end {
            let b = self.runs[r];
            while p < prev_end && self.runs[p].x1 < b.x0 {
                p += 1;
            }
            let mut q = p;
            while q < prev_end && self.runs[q].x0 <= b.x1 {
                if !self.union(q as u32, r as u32) {
                    self.cycles[r] += 1;
                }
                q += 1;
            }
        }
    }

    /// Ends a labelling begun with [`Labeller::begin`] and returns its components in the
    /// raster order of their top-left pixel.
    pub(crate) fn finish(&mut self) -> &[Component] {
        self.end_row();
        self.gather()
    }

    /// Starts a labelling of one horizontal band of a binary image (`rows`, whole rows of
    /// `width` bytes, the first of them row `y0` of the image), for [`Labeller::merge`]
    /// ([`Labeller::label`] labels a whole image as one band): its runs and their joins
    /// within the band, without the components.
    pub(crate) fn label_band(&mut self, y0: usize, rows: &[u8], width: usize) {
        self.begin();
        if width > 0 {
            for (i, row) in rows.chunks_exact(width).enumerate() {
                self.add_row((y0 + i) as u32, 0, row);
            }
        }
        self.end_row();
    }

    /// Labels a binary image from the labellings of its horizontal bands
    /// ([`Labeller::label_band`], top to bottom, each band's first row following the last
    /// one's): the same components, in the same order, and the same runs as
    /// [`Labeller::label`] on the whole image. Only the runs of the rows where two bands
    /// meet are joined here, and the components gathered; the scan of the pixels was the
    /// bands' (on their own threads, [`crate::Search::parallel`]).
    pub(crate) fn merge(&mut self, bands: &[Labeller]) -> &[Component] {
        self.begin();
        for band in bands {
            let off = self.runs.len();
            // The runs of the previous band's last row: the joins across the boundary.
            let prev = self.runs.last().map(|last| {
                let y = last.y;
                let start = off - self.runs.iter().rev().take_while(|r| r.y == y).count();
                (y, start, off)
            });
            self.runs.extend_from_slice(&band.runs);
            self.cycles.extend_from_slice(&band.cycles);
            self.parent
                .extend(band.parent.iter().map(|&p| p + off as u32));
            if let (Some((py, start, _)), Some(first)) = (prev, band.runs.first())
                && py + 1 == first.y
            {
                let end = off + band.runs.iter().take_while(|r| r.y == first.y).count();
                self.join((start, off), (off, end));
            }
        }
        self.gather()
    }

    /// The components of the runs and their joins, in order of each component's first run
    /// (`run_component` filled on the way).
    fn gather(&mut self) -> &[Component] {
        // Gather statistics per root, in order of each component's first run. A root is
        // its component's first run, so its component is known (in `run_component`) by
        // the time any other run of it comes.
        self.run_component.clear();
        for i in 0..self.runs.len() {
            // A run's parent is never after it (a root is its component's first run), so
            // in run order the parent's parent is already the root.
            let p = self.parent[i] as usize;
            let root = self.parent[p] as usize;
            self.parent[i] = root as u32;
            let run = self.runs[i];
            let len = run.x1 - run.x0;
            if root == i {
                self.run_component.push(self.components.len() as u32);
                self.components.push(Component {
                    pixels: len,
                    x_min: run.x0,
                    x_max: run.x1 - 1,
                    y_min: run.y,
                    y_max: run.y,
                    start_x: run.x0,
                    holes: self.cycles[i],
                });
            } else {
                let s = self.run_component[root];
                self.run_component.push(s);
                let c = &mut self.components[s as usize];
                c.pixels += len;
                c.x_min = c.x_min.min(run.x0);
                c.x_max = c.x_max.max(run.x1 - 1);
                c.y_max = c.y_max.max(run.y);
                c.holes += self.cycles[i];
            }
        }
        &self.components
    }

    /// The components of the last labelling ([`Labeller::label`], [`Labeller::merge`],
    /// [`Labeller::finish`]).
    pub(crate) fn components(&self) -> &[Component] {
        &self.components
    }

    /// The runs of the last [`Labeller::label`] call in raster order, as `(component, y,
    /// x0, x1)` (`x1` exclusive; `component` indexes the slice that call returned).
    pub(crate) fn runs(&self) -> impl Iterator<Item = (usize, u32, u32, u32)> + '_ {
        self.runs
            .iter()
            .zip(&self.run_component)
            .map(|(r, &c)| (c as usize, r.y, r.x0, r.x1))
    }

    fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let gp = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = gp;
            i = gp;
        }
        i
    }

    /// Joins the components of runs `a` and `b`; `false` if they were one already.
    fn union(&mut self, a: u32, b: u32) -> bool {
        let ra = self.find(a);
        let rb = self.find(b);
        // The smaller index stays root, so a root is always its component's first run.
        if ra < rb {
            self.parent[rb as usize] = ra;
        } else if rb < ra {
            self.parent[ra as usize] = rb;
        }
        ra != rb
    }
}

/// The dark pixels (`DARK`, 1; light is 0) of up to 64 bytes as a bit mask, bit `i` for
/// byte `i`: eight bytes at a time, whose low bits one multiplication gathers into the
/// top byte.
#[inline]
fn dark_mask(bytes: &[u8]) -> u64 {
    const LOW: u64 = 0x0101_0101_0101_0101;
    const GATHER: u64 = 0x0102_0408_1020_4080;
    let mut m = 0u64;
    let mut words = bytes.chunks_exact(8);
    for (k, c) in words.by_ref().enumerate() {
        let w = u64::from_le_bytes(c.try_into().unwrap_or([0; 8])) & LOW;
        m |= (w.wrapping_mul(GATHER) >> 56) << (8 * k);
    }
    let done = bytes.len() - words.remainder().len();
    for (i, &v) in words.remainder().iter().enumerate() {
        m |= u64::from(v & DARK) << (done + i);
    }
    m
}

/// The runs of the dark bits of `m` (a block of `len <= 64` pixels from pixel `base` on;
/// bits at or past `len` are clear) passed to `push` as `(start, end)` pixel ranges, end
/// exclusive. `start` carries a run still open at the block's end into the next block
/// (the caller closes the last one at the row's end).
#[inline]
fn runs_of_mask(
    m: u64,
    len: usize,
    base: usize,
    start: &mut Option<usize>,
    push: &mut impl FnMut(usize, usize),
) {
    let mut pos = 0u32;
    loop {
        // The bits at or past `pos`.
        let from = if pos >= 64 { 0 } else { u64::MAX << pos };
        match *start {
            Some(a) => {
                // The first light pixel ends the run (a clear bit past `len` is no pixel).
                let light = !m & from;
                let e = light.trailing_zeros();
                if light == 0 || e as usize >= len {
                    return;
                }
                push(a, base + e as usize);
                *start = None;
                pos = e;
            }
            None => {
                let dark = m & from;
                if dark == 0 {
                    return;
                }
                let s = dark.trailing_zeros();
                *start = Some(base + s as usize);
                pos = s;
            }
        }
    }
}

/// Neighbour offsets clockwise in the image (v down), starting west.
const DIRS: [(i32, i32); 8] = [
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
];

/// For a step in direction `d`, the direction from the new pixel to the light pixel checked
/// just before (direction `d - 1` from the old pixel).
const BACK: [usize; 8] = [6, 6, 0, 0, 2, 2, 4, 4];

/// Traces the outer border of the component whose top-left pixel is `(sx, sy)`, clockwise in
/// the image, into `out` (pixel coordinates of border pixels, each visit once per pass).
///
/// The component must not touch the frame border (callers reject those first), so every
/// neighbour visited is inside the image. Stops after `max_len` points and returns `false`
/// in that case (a contour that long is not a candidate anyway).
pub fn trace_outer(
    bin: &[u8],
    width: usize,
    sx: u32,
    sy: u32,
    max_len: usize,
    out: &mut Vec<[i32; 2]>,
) -> bool {
    out.clear();
    let w = width as isize;
    let start = sy as isize * w + sx as isize;
    let offs: [isize; 8] = DIRS.map(|(dx, dy)| dy as isize * w + dx as isize);
    let dark = |i: isize| bin.get(i as usize).copied() == Some(DARK);
    out.push([sx as i32, sy as i32]);
    // The west neighbour of the start is light; search clockwise from it.
    let mut cur = start;
    let mut back = 0usize; // direction from cur to the light pixel we came from
    let mut first_dir: Option<usize> = None;
    let (mut cx, mut cy) = (sx as i32, sy as i32);
    loop {
        let mut found = None;
        for k in 1..=8 {
            let d = (back + k) % 8;
            if dark(cur + offs[d]) {
                found = Some(d);
                break;
            }
        }
        let Some(d) = found else {
            return true; // isolated pixel
        };
        if cur == start {
            match first_dir {
                None => first_dir = Some(d),
                Some(f) if f == d => {
                    out.pop(); // the start was pushed twice
                    return true;
                }
                Some(_) => {}
            }
        }
        cur += offs[d];
        cx += DIRS[d].0;
        cy += DIRS[d].1;
        // The light pixel checked just before `d`, as seen from the new pixel.
        back = BACK[d];
        out.push([cx, cy]);
        if out.len() > max_len {
            return false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(rows: &[&str]) -> (Vec<u8>, usize) {
        let w = rows[0].len();
        let bin = rows
            .iter()
            .flat_map(|r| r.bytes().map(|b| u8::from(b == b'#')))
            .collect();
        (bin, w)
    }

    /// The holes of the component of `runs` written out: the 4-connected light regions of
    /// an image holding only its pixels (with a light frame around), less the outside one.
    fn holes_by_flood_fill(runs: &[(u32, u32, u32)], w: usize, h: usize) -> u32 {
        let (fw, fh) = (w + 2, h + 2);
        let mut dark = vec![false; fw * fh];
        for &(y, x0, x1) in runs {
            for x in x0..x1 {
                dark[(y as usize + 1) * fw + x as usize + 1] = true;
            }
        }
        let mut seen = dark.clone();
        let mut regions = 0;
        for start in 0..fw * fh {
            if seen[start] {
                continue;
            }
            regions += 1;
            seen[start] = true;
            let mut stack = vec![start];
            while let Some(i) = stack.pop() {
                let (x, y) = (i % fw, i / fw);
                let next = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < fw).then(|| i + 1),
                    (y > 0).then(|| i - fw),
                    (y + 1 < fh).then(|| i + fw),
                ];
                for j in next.into_iter().flatten() {
                    if !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        regions - 1
    }

    #[test]
    fn counts_holes() {
        let (bin, w) = parse(&[
            "#####..#.#.", //
            "#.#.#...#..", //
            "#####..#.#.", //
            "...........", //
            ".....#.....", //
            "....#.#....",
            ".....#.....",
        ]);
        let mut l = Labeller::new();
        let holes: Vec<u32> = l.label(&bin, w).iter().map(|c| c.holes).collect();
        // A ring with a bar (two holes), an X of diagonal pixels (a light pixel at its
        // centre, open along the diagonals: none) and a diamond (one).
        assert_eq!(holes, vec![2, 0, 1]);
    }

    proptest::proptest! {
        /// Every component's hole count is the number of light regions it encloses, on
        /// random images of every density.
        #[test]
        fn holes_are_the_enclosed_light_regions(
            w in 1usize..20,
            h in 1usize..20,
            seed in proptest::prelude::any::<u64>(),
            density in 1u64..7,
        ) {
            let bin = crate::test_bytes(seed, w * h, |_, state| u8::from(state % 8 < density));
            let mut l = Labeller::new();
            let comps = l.label(&bin, w).to_vec();
            let runs: Vec<_> = l.runs().collect();
            for (k, c) in comps.iter().enumerate() {
                let own: Vec<_> = runs
                    .iter()
                    .filter(|r| r.0 == k)
                    .map(|&(_, y, x0, x1)| (y, x0, x1))
                    .collect();
                proptest::prop_assert_eq!(c.holes, holes_by_flood_fill(&own, w, h), "component {}", k);
            }
        }

        /// Labelling an image in horizontal bands and merging them gives the components,
        /// their order and the runs of labelling it whole, wherever the bands are cut
        /// (empty rows at a cut included).
        #[test]
        fn merged_bands_label_as_the_whole_image(
            w in 1usize..24,
            h in 1usize..24,
            seed in proptest::prelude::any::<u64>(),
            density in 1u64..6,
            cuts in proptest::collection::vec(0usize..24, 0..4),
        ) {
            let bin = crate::test_bytes(seed, w * h, |i, state| {
                // Some blank rows, so that a cut can fall on one.
                u8::from(i / w % 5 != 4 && state % 7 < density)
            });
            let mut whole = Labeller::new();
            let expected = whole.label(&bin, w).to_vec();
            let expected_runs: Vec<_> = whole.runs().collect();
            let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % h).collect();
            cuts.push(0);
            cuts.push(h);
            cuts.sort_unstable();
            cuts.dedup();
            let mut bands = vec![Labeller::new(); cuts.len() - 1];
            for (band, pair) in bands.iter_mut().zip(cuts.windows(2)) {
                band.label_band(pair[0], &bin[pair[0] * w..pair[1] * w], w);
            }
            let mut merged = Labeller::new();
            // Twice on one labeller, so that stale state would show.
            merged.label(&bin, w);
            proptest::prop_assert_eq!(merged.merge(&bands).to_vec(), expected);
            proptest::prop_assert_eq!(merged.runs().collect::<Vec<_>>(), expected_runs);
        }
    }

    #[test]
    fn labels_with_8_connectivity() {
        let (bin, w) = parse(&[
            "##...#", //
            "..#..#", //
            "......", //
            "###..#",
        ]);
        let mut l = Labeller::new();
        let comps = l.label(&bin, w).to_vec();
        assert_eq!(comps.len(), 4);
        assert_eq!(comps[0].pixels, 3);
        assert_eq!((comps[0].x_min, comps[0].x_max, comps[0].y_max), (0, 2, 1));
        assert_eq!(comps[1].pixels, 2);
        assert_eq!(
            (comps[2].pixels, comps[2].start_x, comps[2].y_min),
            (3, 0, 3)
        );
        assert_eq!(comps[3].pixels, 1);
    }

    /// The dark runs of `row` found byte by byte: `(start, end)`, end exclusive.
    fn runs_by_bytes(row: &[u8]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        let mut x = 0;
        while x < row.len() {
            if row[x] != DARK {
                x += 1;
                continue;
            }
            let a = x;
            while x < row.len() && row[x] == DARK {
                x += 1;
            }
            out.push((a as u32, x as u32));
        }
        out
    }

    /// The runs `add_row` found for one row given at `x0`, as `(start, end)` from `x0`.
    fn runs_of_row(row: &[u8], x0: u32) -> Vec<(u32, u32)> {
        let mut l = Labeller::new();
        l.begin();
        l.add_row(0, x0, row);
        l.runs.iter().map(|r| (r.x0 - x0, r.x1 - x0)).collect()
    }

    #[test]
    fn add_row_finds_every_run_boundary() {
        for len in (0..40).chain([63, 64, 65, 127, 128, 129, 200]) {
            for at in 0..len {
                let mut row = vec![0u8; len];
                row[at] = DARK;
                assert_eq!(runs_of_row(&row, 3), runs_by_bytes(&row), "{len} {at}");
                let mut row = vec![DARK; len];
                row[at] = 0;
                assert_eq!(runs_of_row(&row, 0), runs_by_bytes(&row), "{len} {at}");
            }
            for fill in [0, DARK] {
                let row = vec![fill; len];
                assert_eq!(runs_of_row(&row, 5), runs_by_bytes(&row), "{len} {fill}");
            }
        }
    }

    proptest::proptest! {
        /// The runs read from the bit masks are the runs byte by byte, for rows of any
        /// length and texture (runs of 1 to 80 pixels).
        #[test]
        fn add_row_runs_are_the_byte_runs(
            pieces in proptest::collection::vec((proptest::prelude::any::<bool>(), 1usize..80), 0..20),
            x0 in 0u32..100,
        ) {
            let row: Vec<u8> = pieces
                .iter()
                .flat_map(|&(dark, n)| std::iter::repeat_n(if dark { DARK } else { 0 }, n))
                .collect();
            proptest::prop_assert_eq!(runs_of_row(&row, x0), runs_by_bytes(&row));
        }
    }

    #[test]
    fn u_shape_merges_late() {
        let (bin, w) = parse(&[
            "#...#", //
            "#...#", //
            "#####",
        ]);
        let mut l = Labeller::new();
        let comps = l.label(&bin, w);
        assert_eq!(comps.len(), 1);
        assert_eq!(comps[0].pixels, 9);
    }

    #[test]
    fn traces_a_square_ring_clockwise() {
        let (bin, w) = parse(&[
            ".......", //
            ".####..", //
            ".#..#..", //
            ".#..#..", //
            ".####..", //
            ".......",
        ]);
        let mut pts = Vec::new();
        assert!(trace_outer(&bin, w, 1, 1, 100, &mut pts));
        assert_eq!(pts.len(), 12);
        assert_eq!(pts[0], [1, 1]);
        assert_eq!(pts[1], [2, 1]);
        assert_eq!(pts[3], [4, 1]);
        assert_eq!(pts[6], [4, 4]);
        assert_eq!(pts[11], [1, 2]);
    }

    #[test]
    fn traces_thin_and_single_shapes() {
        let (bin, w) = parse(&[
            ".....", //
            ".#...", //
            "..#..", //
            ".#.#.", //
            ".....",
        ]);
        let mut pts = Vec::new();
        assert!(trace_outer(&bin, w, 1, 1, 100, &mut pts));
        // A Y of single pixels: the junction is passed once per branch.
        assert_eq!(pts, vec![[1, 1], [2, 2], [3, 3], [2, 2], [1, 3], [2, 2]]);
        let (bin, w) = parse(&["...", ".#.", "..."]);
        assert!(trace_outer(&bin, w, 1, 1, 100, &mut pts));
        assert_eq!(pts, vec![[1, 1]]);
    }
}
