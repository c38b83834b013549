//! The detector: grey frame in, refined marker quadrilaterals out (spec 3.4).
//!
//! A [`Detector`] owns every buffer of every stage (smoothed frame, tile statistics, binary
//! image, runs and components, contour, edge points, output quads). Buffers grow to fit the
//! first frame of a size and are then reused, so a steady stream of frames of one size is
//! detected without touching the heap (an integration test counts allocations to prove it).
//!
//! The stages, and what each may reject, are listed in the crate's documentation. There is
//! one way through them, `Detector::run`; the entry points differ only in how they hand
//! the work out ([`Search`]: the whole frame or regions of it, the scale of the quad
//! search, the calling thread or rayon's), as ripgrep's `search` and `search_parallel` do.
//! Nothing is carried from one detection to the next but the buffers: what one stage hands
//! the next within a detection (the quads, the readings the threads made early) is cleared
//! at its start.

use std::time::Instant;

use crate::cluster::Clusterer;
use crate::config::DetectorConfig;
use crate::contour::Labeller;
use crate::decode::Decoded;
use crate::dictionary::Dictionary;
use crate::error::FiducialError;
use crate::image::{Corners, GrayView};
use crate::quad::QuadLimits;
use crate::refine::Refiner;
use crate::roi::{Region, merge_overlapping};
use crate::split::{LIGHT_CUT, LIGHT_CUT_MIN_CONTRAST, Rect, SplitParams, Splitter};
use crate::stages::{DecodeContext, Decoding, Examined, Quad, Scan, push_unique, refine_candidate};
use crate::threshold::Binarizer;

/// The size of one search's binary image: `factor` (1 to 4) is the scale of the quad
/// search, `bands` the labellings of a banded binarization (0: labelled whole).
#[derive(Debug, Clone, Copy)]
struct ScanSize {
    w: usize,
    h: usize,
    factor: usize,
    bands: usize,
}

/// The quads the threads read as they found them in stage 3 of one detection (the first
/// `quads` of the list; their markers are already in the detector's readings) and how many
/// of those readings were blurred ones: stage 5 reads the rest.
#[derive(Debug, Default, Clone, Copy)]
struct Read {
    quads: usize,
    blurred: usize,
}

/// Lap times of the stages.
struct Clock(Instant);

impl Clock {
    /// The time since the last lap (or the start).
    fn lap(&mut self) -> std::time::Duration {
        let now = Instant::now();
        let d = now - self.0;
        self.0 = now;
        d
    }
}

/// Two outlines of one marker: their centres are within half a side of each other.
fn same_place(a: &Corners, b: &Corners) -> bool {
    let centre = |c: &Corners| {
        c.iter()
            .fold([0.0, 0.0], |s, p| [s[0] + p.x / 4.0, s[1] + p.y / 4.0])
    };
    let (ca, cb) = (centre(a), centre(b));
    // Squared: centre distance < half the shorter first side. This runs for every pair of
    // a re-cut candidate and a known quad (about a million pairs on a cluttered 4K frame),
    // where square roots cost a tenth of the detection.
    let side2 = (a[1] - a[0])
        .norm_squared()
        .min((b[1] - b[0]).norm_squared());
    let (dx, dy) = (ca[0] - cb[0], ca[1] - cb[1]);
    dx * dx + dy * dy < 0.25 * side2
}

/// Where and how one detection searches ([`Detector::detect_with`]); the default is
/// [`Detector::detect`]'s: the whole frame, at full resolution, on the calling thread,
/// `out` cleared first.
///
/// Every combination runs the same stages; these only say where they look and how their
/// work is handed out. Build one with [`Search::whole_frame`] or [`Search::in_regions`] and
/// the methods below, or by its fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Search<'r> {
    /// `None`: the whole frame. `Some(regions)`: only these rectangles of it
    /// (tracking-guided detection, [`Region`]). Every stage runs on each region alone,
    /// through a view of the frame (no copy), and corners come back in the frame's
    /// coordinates. Regions are cut to the frame, grown to the binarization's tile grid of
    /// the scale searched ([`Region::aligned`]: a marker well inside then gets the corners
    /// a whole-frame search at that scale gives it) and overlapping ones merged; a marker
    /// read in two regions is reported once. A marker is found only if it lies wholly
    /// inside a region, the detector's `border_margin` from its edge.
    pub regions: Option<&'r [Region]>,
    /// The scale of the quad search, 1 to 4 (0 reads as 1, more than 4 as 4): with `s > 1`
    /// the frame (or region) is averaged over `s x s` blocks and quads are found on that
    /// small image, to find big markers cheaply; their corners are refined and decoded at
    /// full resolution, so corner accuracy is that of a full-resolution search. Markers
    /// whose side is under `s` times `min_side` are not found. A tracker that knows its
    /// leaders are near passes 2 or more.
    pub scale: usize,
    /// Whether to run on the threads of the current rayon pool (crate feature `parallel`;
    /// without it, on the calling thread with the same output): binarization cut into
    /// horizontal bands, each labelled on the thread that cut it, and the components'
    /// tracing, fit, refinement and decoding handed out one at a time, the largest first
    /// (the markers, their order and every counter are those of the calling thread's
    /// search; a test checks it). A frame or region under a megapixel is searched on the
    /// calling thread all the same, where the threads' start-up costs more than they save.
    /// The search may then allocate per frame (rayon's job queue).
    pub parallel: bool,
    /// Whether the markers already in `out` are kept: `false` clears it first; `true` adds
    /// this search's markers to them, a marker read twice kept once (the reading with fewer
    /// corrected bits, then higher contrast). For regions searched at different scales
    /// (e.g. a leader's region at a coarse scale and a narrow face's box at full
    /// resolution), one search per scale, the later ones appending.
    pub append: bool,
}

impl Default for Search<'_> {
    /// [`Search::whole_frame`].
    fn default() -> Self {
        Self {
            regions: None,
            scale: 1,
            parallel: false,
            append: false,
        }
    }
}

impl<'r> Search<'r> {
    /// The whole frame, at full resolution, on the calling thread, `out` cleared first
    /// ([`Detector::detect`]).
    pub fn whole_frame() -> Self {
        Self::default()
    }

    /// Only `regions` of the frame ([`Search::regions`]), at full resolution, on the
    /// calling thread, `out` cleared first.
    pub fn in_regions(regions: &'r [Region]) -> Self {
        Self {
            regions: Some(regions),
            ..Self::default()
        }
    }

    /// This search with the quads searched at `1 / scale` of the resolution
    /// ([`Search::scale`]).
    pub fn at_scale(self, scale: usize) -> Self {
        Self { scale, ..self }
    }

    /// This search on the threads of the current rayon pool ([`Search::parallel`]).
    pub fn in_parallel(self) -> Self {
        Self {
            parallel: true,
            ..self
        }
    }

    /// This search adding to what `out` holds ([`Search::append`]).
    pub fn appending(self) -> Self {
        Self {
            append: true,
            ..self
        }
    }
}

/// Frames (or regions) under this many pixels are searched on the calling thread even when
/// [`Search::parallel`] asks for rayon's: below it the threads' start-up costs more than
/// they save.
#[cfg(feature = "parallel")]
const PARALLEL_MIN_PIXELS: usize = 1 << 20;

/// The workers a search of `pixels` pixels runs on: the current rayon pool's threads when
/// `parallel` asks for them and the image is large enough, else 1 (the calling thread).
fn threads_for(parallel: bool, pixels: usize) -> usize {
    #[cfg(feature = "parallel")]
    if parallel && pixels >= PARALLEL_MIN_PIXELS {
        return rayon::current_num_threads();
    }
    #[cfg(not(feature = "parallel"))]
    let _ = (parallel, pixels);
    1
}

/// Runs `job`, for `threads > 1` as one job of the current rayon pool: the stages' parallel
/// parts then start from one of its threads, and the calling thread (outside the pool) is
/// woken once at the end rather than after each stage (worth about 0.05 of the frame at
/// 1920x1080 on 2 cores).
fn on_pool<R: Send>(threads: usize, job: impl FnOnce() -> R + Send) -> R {
    #[cfg(feature = "parallel")]
    if threads > 1 {
        return rayon::scope(|_| job());
    }
    #[cfg(not(feature = "parallel"))]
    let _ = threads;
    job()
}

/// The marker detector; reuse one per stream of frames.
///
/// It reads one or several dictionaries in one pass: each quad's cells are sampled once per
/// distinct grid (family and white reference), and that reading is looked up in every
/// dictionary of that grid (e.g. `DICT_6X6_250` and `tag36h11` share one reading). A quad
/// that matches in several dictionaries is reported once, from the dictionary with the
/// fewest corrected bits (the earlier one in the list on a tie).
#[derive(Debug, Clone)]
pub struct Detector {
    config: DetectorConfig,
    dictionaries: Vec<Dictionary>,
    /// For each dictionary, the first dictionary in the list read with the same grid.
    grid_of: Vec<usize>,
    binarizer: Binarizer,
    bin: Vec<u8>,
    labeller: Labeller,
    /// One labeller per band of a parallel search's binarization: each band's
    /// rows are labelled on the thread that cut them, then merged into `labeller`.
    band_labellers: Vec<Labeller>,
    contour: Vec<[i32; 2]>,
    refiner: Refiner,
    quads: Vec<Quad>,
    /// Boxes of large components that gave no quad, re-cut by [`Splitter`].
    retry: Vec<Rect>,
    /// Which components of the last scan gave a box to `retry`.
    retried: Vec<bool>,
    /// Their dark runs, `[y, x0, x1)` in raster order: the pixels the re-cut cuts again.
    retry_runs: Vec<[u32; 3]>,
    splitter: Splitter,
    /// Boundary clustering of the same boxes, after the re-cut.
    clusterer: Clusterer,
    /// The decimated frame of a coarse scan ([`Search::scale`]).
    small: Vec<u8>,
    /// The merged regions of a search in regions ([`Search::regions`]).
    regions: Vec<Region>,
    /// One region's markers before they are moved into frame coordinates.
    region_out: Vec<Decoded>,
    /// Per-thread scratch of a parallel search ([`Search::parallel`]).
    workers: Vec<crate::parallel::Worker>,
    /// Scratch of decoding on the calling thread.
    decoding: Decoding,
    /// Scratch of the parallel paths' index-ordered merges.
    merge: crate::parallel::Merge,
    /// The markers read by stages 3 (on threads) and 5 of the current detection, in quad
    /// order, before stage 6 reconciles them.
    readings: Vec<Decoded>,
    /// The work counters of the last detection.
    stats: DetectStats,
}

/// How much work the last detection did, stage by stage ([`Detector::stats`]): where the
/// time of a frame goes. A frame of synthetic markers has about as many components big
/// enough to examine as markers, and no second look; a real photograph has hundreds of
/// components, and the second look (`second_look_px`) is what costs most on it. After
/// a search in regions ([`Search::regions`]), the counters are the last region's.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct DetectStats {
    /// Dark components of the binary image.
    pub components: usize,
    /// Components big enough to hold a marker (the rest are dropped unexamined).
    pub examined: usize,
    /// Quads refined by the first pass (one per component that was a quadrilateral).
    pub first_quads: usize,
    /// Components that gave no quad and were handed to the second look.
    pub retries: usize,
    /// Pixels of the boxes the second look read (each box once per cut it made).
    pub second_look_px: u64,
    /// Quads the second look added (light cut, re-cut, boundary clusters).
    pub second_quads: usize,
    /// Quads read by the decoder.
    pub decoded: usize,
    /// Of those, read once more as motion-blurred markers.
    pub blurred: usize,
    /// Wall-clock time of each stage on the calling thread: binarization, labelling,
    /// examining the components (trace, fit, refine), the second look (light cut, re-cut,
    /// boundary clusters) and decoding.
    pub time: StageTimes,
}

/// Wall-clock time of each stage of the last detection ([`DetectStats::time`]).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct StageTimes {
    /// Binarization (and, in a banded-parallel scan, the bands' own labelling).
    pub binarize: std::time::Duration,
    /// Labelling the components (in a banded-parallel scan, merging the bands').
    pub label: std::time::Duration,
    /// Tracing, fitting and refining the components (in a parallel scan, decoding too).
    pub examine: std::time::Duration,
    /// The second look at components that gave no quad.
    pub second_look: std::time::Duration,
    /// Decoding the quads.
    pub decode: std::time::Duration,
}

fn ms(d: std::time::Duration) -> f64 {
    1e3 * d.as_secs_f64()
}

impl std::fmt::Display for DetectStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "components {} examined {} quads {} retries {} second-look px {} second quads {} \
             decoded {} blurred {} | ms: binarize {:.3} label {:.3} examine {:.3} second look {:.3} \
             decode {:.3}",
            self.components,
            self.examined,
            self.first_quads,
            self.retries,
            self.second_look_px,
            self.second_quads,
            self.decoded,
            self.blurred,
            ms(self.time.binarize),
            ms(self.time.label),
            ms(self.time.examine),
            ms(self.time.second_look),
            ms(self.time.decode),
        )
    }
}

impl Default for Detector {
    /// Default settings and the paper's dictionary.
    fn default() -> Self {
        Self::new(DetectorConfig::default())
    }
}

impl Detector {
    /// A detector with the given settings for the paper's dictionary
    /// ([`Dictionary::paper`]); buffers grow on the first frame.
    pub fn new(config: DetectorConfig) -> Self {
        Self::with_dictionary(config, Dictionary::paper().clone())
    }

    /// A detector that reads codes of `dictionary`.
    pub fn with_dictionary(config: DetectorConfig, dictionary: Dictionary) -> Self {
        Self::build(config, vec![dictionary])
    }

    /// A detector that reads every dictionary of `dictionaries` in one pass (see the type's
    /// docs); [`Decoded::dictionary`] is the position in this list.
    pub fn with_dictionaries(
        config: DetectorConfig,
        dictionaries: Vec<Dictionary>,
    ) -> Result<Self, FiducialError> {
        if dictionaries.is_empty() {
            return Err(FiducialError::EmptyDictionary);
        }
        Ok(Self::build(config, dictionaries))
    }

    fn build(config: DetectorConfig, dictionaries: Vec<Dictionary>) -> Self {
        let key = |d: &Dictionary| (d.family(), d.uses_quiet_zone());
        let grid_of = (0..dictionaries.len())
            .map(|i| {
                (0..=i)
                    .find(|&j| key(&dictionaries[j]) == key(&dictionaries[i]))
                    .unwrap_or(i)
            })
            .collect();
        Self {
            config,
            decoding: Decoding::new(dictionaries.len()),
            merge: Default::default(),
            readings: Vec::new(),
            grid_of,
            dictionaries,
            binarizer: Binarizer::default(),
            bin: Vec::new(),
            labeller: Labeller::default(),
            band_labellers: Vec::new(),
            contour: Vec::new(),
            refiner: Refiner::default(),
            quads: Vec::new(),
            retry: Vec::new(),
            retried: Vec::new(),
            retry_runs: Vec::new(),
            splitter: Splitter::default(),
            clusterer: Clusterer::default(),
            small: Vec::new(),
            regions: Vec::new(),
            region_out: Vec::new(),
            workers: Vec::new(),
            stats: DetectStats::default(),
        }
    }

    /// The (first) dictionary codes are looked up in.
    pub fn dictionary(&self) -> &Dictionary {
        &self.dictionaries[0]
    }

    /// Every dictionary codes are looked up in, in the order given.
    pub fn dictionaries(&self) -> &[Dictionary] {
        &self.dictionaries
    }

    /// Finds and decodes the markers in `img` into `out` (cleared first; it keeps its
    /// capacity, so a reused `Vec` makes steady-state detection allocation-free). Each
    /// [`Decoded`] carries the dictionary index, code, Hamming distance corrected, corners
    /// in the marker's own NW, NE, SE, SW order and contrast/confidence. Returns the number
    /// of quads examined.
    ///
    /// ```
    /// use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, RenderOptions, render_marker};
    ///
    /// // Marker 7 of the paper's dictionary, 10 px a cell, with a wide white margin.
    /// let dict = Dictionary::paper();
    /// let options = RenderOptions { px_per_cell: 10, quiet_cells: 4 };
    /// let marker = render_marker(dict.family(), dict.codes()[7], &options)?;
    /// let frame = GrayView::new(marker.pixels(), marker.width(), marker.height())?;
    ///
    /// let mut detector = Detector::new(DetectorConfig::default());
    /// let mut found = Vec::new();
    /// detector.detect(&frame, &mut found);
    /// assert_eq!(found.len(), 1);
    /// assert_eq!(found[0].index, 7);
    /// // Corners in the marker's own NW, NE, SE, SW order, sub-pixel.
    /// for (got, want) in found[0].corners.iter().zip(marker.corners()) {
    ///     assert!((got - want).norm() < 0.1, "{got} vs {want}");
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn detect(&mut self, img: &GrayView<'_>, out: &mut Vec<Decoded>) -> usize {
        self.detect_with(img, &Search::whole_frame(), out)
    }

    /// Finds and decodes the markers in `img` as `search` says ([`Search`]): in the whole
    /// frame or in regions of it, at full or a coarser scale, on the calling thread or on
    /// the threads of the current rayon pool, replacing or adding to what `out` holds. Every
    /// way runs the same stages (the crate's documentation lists them and what each may
    /// reject); the options only say where the stages look and how their work is handed
    /// out. Each [`Decoded`] is as in [`Detector::detect`], its corners in `img`'s
    /// coordinates. `out` keeps its capacity; once the buffers have grown to the largest
    /// frame or region, a steady stream allocates nothing (on the calling thread; rayon's
    /// job queue may allocate). Returns the number of quads examined (over every region).
    ///
    /// ```
    /// use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Region, RenderOptions,
    ///     Search, render_marker};
    ///
    /// // Marker 7 of the paper's dictionary, 20 px a cell, with a wide white margin.
    /// let dict = Dictionary::paper();
    /// let options = RenderOptions { px_per_cell: 20, quiet_cells: 4 };
    /// let marker = render_marker(dict.family(), dict.codes()[7], &options)?;
    /// let frame = GrayView::new(marker.pixels(), marker.width(), marker.height())?;
    /// let (w, h) = (marker.width(), marker.height());
    ///
    /// let mut detector = Detector::new(DetectorConfig::default());
    /// let mut found = Vec::new();
    /// // The whole frame, the quads searched at half resolution (big markers, cheaply);
    /// // corners are still refined at full resolution.
    /// detector.detect_with(&frame, &Search::whole_frame().at_scale(2), &mut found);
    /// assert_eq!(found.len(), 1);
    /// // Only where a tracker expects the marker: the region holds all of it.
    /// let around = [Region::new(0, 0, w, h)];
    /// detector.detect_with(&frame, &Search::in_regions(&around), &mut found);
    /// assert_eq!(found[0].index, 7);
    /// // A region without it adds nothing to what `found` holds.
    /// let corner = [Region::new(0, 0, 40, 40)];
    /// detector.detect_with(&frame, &Search::in_regions(&corner).appending(), &mut found);
    /// assert_eq!(found.len(), 1);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn detect_with(
        &mut self,
        img: &GrayView<'_>,
        search: &Search<'_>,
        out: &mut Vec<Decoded>,
    ) -> usize {
        let factor = search.scale.clamp(1, 4);
        match search.regions {
            None => {
                let threads = threads_for(search.parallel, img.width() * img.height());
                if search.append {
                    on_pool(threads, || self.run_into(img, factor, threads, (0, 0), out))
                } else {
                    on_pool(threads, || self.run(img, factor, threads, out))
                }
            }
            Some(regions) => {
                if !search.append {
                    out.clear();
                }
                self.run_in_regions(img, regions, factor, search.parallel, out)
            }
        }
    }

    /// One detection, stage by stage (the crate's documentation says what each stage may
    /// reject): the quad search at `1 / factor` of the resolution (corners are always
    /// refined on `img` itself), its work handed to `threads` workers (1: the calling thread
    /// alone). `out` is cleared first. Returns the number of quads examined.
    fn run(
        &mut self,
        img: &GrayView<'_>,
        factor: usize,
        threads: usize,
        out: &mut Vec<Decoded>,
    ) -> usize {
        out.clear();
        let mut clock = Clock(Instant::now());
        if let Some(read) = self.find(img, factor, threads, &mut clock) {
            self.decode(img, threads, read);
            self.reconcile(out);
            self.stats.time.decode = clock.lap();
        }
        self.quads.len()
    }

    /// Stages 1 to 4 of one detection (binarize, label, examine, second look): the quads
    /// into `self.quads`, and the stage times into `self.stats`. Returns which of them the
    /// threads already read (stage 5 reads the rest), or `None` when `img` is too small to
    /// search.
    fn find(
        &mut self,
        img: &GrayView<'_>,
        factor: usize,
        threads: usize,
        clock: &mut Clock,
    ) -> Option<Read> {
        self.quads.clear();
        self.stats = DetectStats::default();
        let scan = self.binarize(img, factor, threads)?;
        self.stats.time.binarize = clock.lap();
        self.label(scan);
        self.stats.time.label = clock.lap();
        let read = self.examine(img, scan, threads);
        self.stats.time.examine = clock.lap();
        self.second_look(img, scan);
        self.stats.time.second_look = clock.lap();
        Some(read)
    }

    /// [`Detector::run`] adding to `out`: the markers of `img`, a view whose top-left pixel
    /// is `(x, y)` of the frame, moved into the frame's coordinates and added to those
    /// already there, a marker read twice kept once (fewer bit errors, then higher
    /// contrast).
    fn run_into(
        &mut self,
        img: &GrayView<'_>,
        factor: usize,
        threads: usize,
        (x, y): (usize, usize),
        out: &mut Vec<Decoded>,
    ) -> usize {
        let mut found = std::mem::take(&mut self.region_out);
        let examined = self.run(img, factor, threads, &mut found);
        let (dx, dy) = (x as f64, y as f64);
        for mut d in found.drain(..) {
            for c in &mut d.corners {
                c.x += dx;
                c.y += dy;
            }
            push_unique(out, d);
        }
        self.region_out = found;
        examined
    }

    /// Every stage on each of `regions` alone, through a view of `img` (no copy), the
    /// markers added to `out` ([`Search::regions`] says how regions are cut, grown and
    /// merged).
    fn run_in_regions(
        &mut self,
        img: &GrayView<'_>,
        regions: &[Region],
        factor: usize,
        parallel: bool,
        out: &mut Vec<Decoded>,
    ) -> usize {
        self.regions.clear();
        // Regions start and end on the binarization's tile grid (of the scale searched), so
        // that inside them the tiles, their levels and the binary image are those of a
        // full-frame scan at that scale: a marker well inside a region gets the same outline,
        // hence the same corners, as in full-frame detection (only the region's edge tiles see
        // fewer neighbours).
        let grid = self.config.threshold.tile_side() * factor;
        let (w, h) = (img.width(), img.height());
        self.regions.extend(
            regions
                .iter()
                .filter_map(|r| r.clamped(w, h))
                .map(|r| r.aligned(grid, w, h)),
        );
        merge_overlapping(&mut self.regions);
        let mut examined = 0;
        for i in 0..self.regions.len() {
            let r = self.regions[i];
            let Some(sub) = img.crop(r) else {
                continue;
            };
            let threads = threads_for(parallel, r.area());
            examined += on_pool(threads, || {
                self.run_into(&sub, factor, threads, (r.x, r.y), out)
            });
        }
        examined
    }

    /// The quads of stages 1 to 4 on the whole of `img` at full resolution, not decoded
    /// (`stages_for_tools::find_quads`, for the benchmarks).
    pub(crate) fn find_quads(&mut self, img: &GrayView<'_>) -> &[Quad] {
        let mut clock = Clock(Instant::now());
        self.find(img, 1, 1, &mut clock);
        &self.quads
    }

    /// The work counters of the last detection ([`DetectStats`]).
    pub fn stats(&self) -> DetectStats {
        self.stats
    }

    /// The quads (candidate outlines, decoded or not) of the last detection, in the order
    /// they were found; after a search in regions, the last region's, in its own
    /// coordinates. For visualising and diagnosing what the decoder was given.
    pub fn quads(&self) -> &[Quad] {
        &self.quads
    }

    /// The settings.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// The binary image of the last detection (`width` bytes per row, 1 = dark; at a
    /// coarser scale, of the averaged frame; after a search in regions, of the last
    /// region), for debugging and visualisation.
    pub fn binary(&self) -> &[u8] {
        &self.bin
    }

    /// The most cells across of any dictionary: the narrowest border cell the edge
    /// profiles must stay within.
    fn cells_across(&self) -> f64 {
        self.dictionaries
            .iter()
            .map(|d| f64::from(d.family().width_cells().max(d.family().height_cells())))
            .fold(0.0, f64::max)
    }

    /// The quad limits of a search at `1 / factor` of the resolution.
    fn limits(&self, factor: usize) -> QuadLimits {
        let cfg = &self.config;
        QuadLimits {
            min_side: cfg.min_side / factor as f64,
            min_angle_deg: cfg.min_angle_deg,
            line_tolerance: cfg.line_tolerance,
            line_tolerance_rel: cfg.line_tolerance_rel,
        }
    }

    /// Stage 1, binarize: the binary image of `img` (of its `factor x factor` block means
    /// when `factor > 1`) into `self.bin`. With `threads > 1` at full resolution it is cut
    /// in bands, each band's rows labelled on the thread that cut them while they are in
    /// its cache (stage 2 then only joins the bands). `None` when the frame is too small to
    /// search.
    fn binarize(&mut self, img: &GrayView<'_>, factor: usize, threads: usize) -> Option<ScanSize> {
        let cfg = self.config;
        let f = factor.max(1);
        let (w, h) = if f == 1 {
            (img.width(), img.height())
        } else {
            (img.width() / f, img.height() / f)
        };
        if w < 3 || h < 3 {
            return None;
        }
        // Reserve for the frame size once, so that later frames of this size do not grow
        // the buffers (the run list grows only past one run per 16 pixels).
        if self.bin.capacity() < w * h {
            self.contour.reserve(2 * (w + h) + 16);
            self.quads.reserve(64);
        }
        let mut bands = 0;
        if f == 1 && threads > 1 {
            if self.band_labellers.len() < threads {
                self.band_labellers.resize_with(threads, Labeller::default);
            }
            bands = self.binarizer.binarize_parallel_then(
                img,
                cfg.threshold,
                &mut self.bin,
                &mut self.band_labellers[..threads],
                &|l: &mut Labeller, y0, rows: &[u8]| l.label_band(y0, rows, w),
            );
        } else if f == 1 {
            self.binarizer.binarize(img, cfg.threshold, &mut self.bin);
        } else {
            crate::image::decimate(img, f, &mut self.small);
            let small = GrayView::new(&self.small, w, h).ok()?;
            self.binarizer
                .binarize(&small, cfg.threshold, &mut self.bin);
        }
        Some(ScanSize {
            w,
            h,
            factor: f,
            bands,
        })
    }

    /// Stage 2, label: the dark components of `self.bin` (joining the bands' labellings
    /// after a banded stage 1).
    fn label(&mut self, scan: ScanSize) {
        self.stats.components = if scan.bands > 0 {
            self.labeller
                .merge(&self.band_labellers[..scan.bands])
                .len()
        } else {
            self.labeller.label(&self.bin, scan.w).len()
        };
    }

    /// Stage 3, examine: each component traced, fitted and refined into `self.quads`, or
    /// its box kept in `self.retry` for the second look. With `threads > 1` this runs on
    /// the threads, which at full resolution also read each quad as soon as they find it
    /// (into `self.readings`): the returned [`Read`] says which, for stage 5.
    fn examine(&mut self, img: &GrayView<'_>, scan: ScanSize, threads: usize) -> Read {
        let cfg = self.config;
        let limits = self.limits(scan.factor);
        let cells_across = self.cells_across();
        let ctx = Scan {
            img,
            bin: &self.bin,
            w: scan.w,
            h: scan.h,
            limits: &limits,
            margin: cfg.border_margin.max(1),
            min_side: (cfg.min_side / scan.factor as f64).max(3.0) as u32,
            factor: scan.factor,
            config: &cfg,
            cells_across,
        };
        let components = self.labeller.components();
        self.retry.clear();
        self.retried.clear();
        self.retried.resize(components.len(), false);
        self.stats.examined = components.iter().filter(|c| !ctx.too_small(c)).count();
        self.readings.clear();
        let mut read = Read::default();
        if threads > 1 {
            let dctx = DecodeContext {
                config: &self.config,
                dictionaries: &self.dictionaries,
                grid_of: &self.grid_of,
            };
            // A full-resolution scan on threads decodes its quads as it finds them
            // (stage 5 then reads only the second look's).
            let decode = scan.factor == 1;
            crate::parallel::examine_all(
                &ctx,
                components,
                threads,
                &mut self.workers,
                &mut self.merge,
                decode.then_some(&dctx),
                crate::parallel::Examined {
                    quads: &mut self.quads,
                    readings: &mut self.readings,
                    blurred: &mut read.blurred,
                    retry: &mut self.retry,
                    retried: &mut self.retried,
                },
            );
            if decode {
                read.quads = self.quads.len();
            }
        } else {
            for (i, c) in components.iter().enumerate() {
                match ctx.examine(c, &mut self.contour, &mut self.refiner) {
                    Examined::Quad(q) => self.quads.push(q),
                    Examined::Retry(r) => {
                        self.retry.push(r);
                        self.retried[i] = true;
                    }
                    Examined::Dropped => {}
                }
            }
        }
        self.stats.first_quads = self.quads.len();
        self.stats.retries = self.retry.len();
        read
    }

    /// Stage 4, second look: the boxes of the components that gave no quad cut again
    /// (`split_retries`); the new quads are appended to `self.quads`.
    fn second_look(&mut self, img: &GrayView<'_>, scan: ScanSize) {
        let f = scan.factor;
        // The pixels the re-cut cuts again (it runs on a full-resolution scan only).
        self.retry_runs.clear();
        if f == 1 && !self.retry.is_empty() {
            let retried = &self.retried;
            self.retry_runs.extend(
                self.labeller
                    .runs()
                    .filter(|r| retried[r.0])
                    .map(|(_, y, x0, x1)| [y, x0, x1]),
            );
        }
        // The second look runs on full-resolution pixels: a coarser scan's boxes are scaled
        // up first, so that a coarse or guided scan looks again at the same places as a
        // full-resolution one (a marker merged with its surroundings is as likely at any
        // scale).
        if f > 1 {
            let (fw, fh) = (img.width() as u32, img.height() as u32);
            let s = f as u32;
            for r in &mut self.retry {
                r.x0 *= s;
                r.y0 *= s;
                r.x1 = ((r.x1 + 1) * s - 1).min(fw - 1);
                r.y1 = ((r.y1 + 1) * s - 1).min(fh - 1);
            }
        }
        let full_limits = self.limits(1);
        let cells_across = self.cells_across();
        self.split_retries(img, &full_limits, cells_across, f);
        self.stats.second_quads = self.quads.len() - self.stats.first_quads;
    }

    /// Stage 5, decode: every quad read, the markers added to `self.readings` in quad order
    /// (the quads the threads read in stage 3 of this detection, `read`, are not read again).
    fn decode(&mut self, img: &GrayView<'_>, threads: usize, read: Read) {
        self.decoding.blur.solved_quads = read.blurred;
        let ctx = DecodeContext {
            config: &self.config,
            dictionaries: &self.dictionaries,
            grid_of: &self.grid_of,
        };
        let rest = &self.quads[read.quads..];
        if threads > 1 && rest.len() > 1 {
            crate::parallel::decode_all(
                img,
                &ctx,
                rest,
                threads,
                &mut self.workers,
                &mut self.merge,
                &mut self.decoding,
                &mut self.readings,
            );
        } else {
            for q in rest {
                if let Some(d) = ctx.decode(img, q, &mut self.decoding) {
                    self.readings.push(d);
                }
            }
        }
        self.stats.decoded = self.quads.len();
        self.stats.blurred = self.decoding.blur.solved_quads;
    }

    /// Stage 6, reconcile: the markers read into `out`, a marker read twice reported once
    /// (the reading with fewer corrected bits, then higher contrast).
    fn reconcile(&self, out: &mut Vec<Decoded>) {
        for d in &self.readings {
            push_unique(out, *d);
        }
    }

    /// Re-cuts the components that gave no quad ([`Splitter`]; only after a full-resolution
    /// scan, `factor` 1, as it re-cuts that scan's binary image) and clusters their
    /// boundaries ([`Clusterer`], any scan: it reads the grey image alone), and adds the
    /// quads found there that are not already in the list. `self.retry` is in
    /// full-resolution pixels.
    ///
    /// With [`DetectorConfig::motion_blur`], the box of each such component (up to
    /// [`LIGHT_CUT_MAX_SIDE`]) is first cut at [`LIGHT_CUT`] of the way from the local
    /// minimum to the local maximum. A marker smeared by a motion of two cells or more has
    /// no closed dark outline at the midpoint threshold: where a white data cell lies next
    /// to its one-cell border, the box blur averages the border with that cell and the
    /// border reads light, so the dark component of the marker opens into its inside. Cut
    /// nearer the white level, the smeared border is dark again all round and the outline
    /// closes: it is the marker grown along the motion, whose sides are the marker's own
    /// sides moved outwards by a fraction of the motion, and the refinement on the grey
    /// image takes it from there. On seeds 70,000-70,039 at 9 px of motion blur it turned
    /// 55 of 320 markers with no quad into 17. Only boxes of components the first cut could
    /// not fit are cut, so a frame in which every dark component was a quad pays nothing.
    fn split_retries(
        &mut self,
        img: &GrayView<'_>,
        limits: &QuadLimits,
        cells_across: f64,
        factor: usize,
    ) {
        let area = |r: &Rect| u64::from(r.x1 - r.x0 + 1) * u64::from(r.y1 - r.y0 + 1);
        if self.retry.is_empty() {
            return;
        }
        let cfg = &self.config;
        let params = split_params(cfg, limits);
        let (quads, refiner) = (&mut self.quads, &mut self.refiner);
        let mut add = |coarse: Corners, min_angle_deg: f64, dark_cut: bool| {
            add_refined(
                quads,
                refiner,
                img,
                Candidate {
                    coarse,
                    min_angle_deg,
                    dark_cut,
                },
                cfg,
                cells_across,
            );
        };
        if cfg.motion_blur {
            for &rect in &self.retry {
                if rect.x1 - rect.x0 < LIGHT_CUT_MAX_SIDE && rect.y1 - rect.y0 < LIGHT_CUT_MAX_SIDE
                {
                    self.stats.second_look_px += area(&rect);
                    self.splitter.cut_at(
                        img,
                        None,
                        rect,
                        &params,
                        LIGHT_CUT,
                        LIGHT_CUT_MIN_CONTRAST,
                        |c| add(c, cfg.min_angle_deg, false),
                    );
                }
            }
        }
        let frame = (img.width() * img.height()) as u64;
        let total: u64 = self.retry.iter().map(area).sum();
        if total > frame {
            // Nested boxes: one pass over their union costs less.
            let u = self.retry.iter().fold(self.retry[0], |u, r| Rect {
                x0: u.x0.min(r.x0),
                y0: u.y0.min(r.y0),
                x1: u.x1.max(r.x1),
                y1: u.y1.max(r.y1),
            });
            self.retry.clear();
            self.retry.push(u);
        }
        for &rect in &self.retry {
            let passes = u64::from(factor == 1) + u64::from(cfg.boundary_clusters);
            self.stats.second_look_px += passes * area(&rect);
            if factor == 1 {
                self.splitter
                    .split(img, &self.retry_runs, rect, &params, |c| {
                        add(c, cfg.min_angle_deg, true)
                    });
            }
            // What the re-cut could not separate: clusters of the light/dark boundary.
            if cfg.boundary_clusters {
                let angle = cfg.min_angle_deg.min(crate::cluster::MIN_ANGLE_DEG);
                self.clusterer
                    .clusters(img, rect, &params, |c| add(c, angle, false));
            }
        }
    }
}

/// Boxes of at least this many pixels across are not light-cut: a marker that large has
/// cells of over 20 px, which a motion blur of less than 1.5 cells (30 px) leaves readable
/// at the midpoint threshold.
const LIGHT_CUT_MAX_SIDE: u32 = 160;

/// What the re-cut, the light cut and boundary clustering need from the settings.
fn split_params<'a>(cfg: &DetectorConfig, limits: &'a QuadLimits) -> SplitParams<'a> {
    SplitParams {
        limits,
        border_margin: cfg.border_margin,
        min_side: cfg.min_side.max(3.0) as u32,
    }
}

/// Whether every corner of `inner` lies inside the outline `outer` (clockwise in the image).
fn contains(outer: &Corners, inner: &Corners) -> bool {
    inner.iter().all(|p| {
        (0..4).all(|i| {
            let (a, b) = (outer[i], outer[(i + 1) % 4]);
            (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x) > 0.0
        })
    })
}

/// A quad candidate of the second look: its coarse corners, the sharpest corner its fit
/// accepts (degrees), and whether the re-cut found it ([`Quad`]'s `dark_cut`).
struct Candidate {
    coarse: Corners,
    min_angle_deg: f64,
    dark_cut: bool,
}

/// Refines the coarse corners of a re-cut or light-cut quad on `img` and adds the quad to
/// `quads` unless it is already there: most re-cut components are ones already found (or
/// their parts), so those are skipped before the refinement, by the coarse corners. So
/// is a candidate that lies wholly inside a quad already found: the darker cut splits a
/// marker's inside into blocks of cells, which are not markers (a marker is found inside
/// a dark outline only if it is a component of its own, which the first cut already
/// examined). On the demo's first frame at 640x480 this saved a tenth of the detection:
/// two such blocks, one refined for nothing and one refined and decoded for nothing.
fn add_refined(
    quads: &mut Vec<Quad>,
    refiner: &mut Refiner,
    img: &GrayView<'_>,
    candidate: Candidate,
    cfg: &DetectorConfig,
    cells_across: f64,
) {
    let Candidate {
        coarse,
        min_angle_deg,
        dark_cut,
    } = candidate;
    if quads
        .iter()
        .any(|q| same_place(&q.corners, &coarse) || contains(&q.corners, &coarse))
    {
        return;
    }
    let Some((c, contrast)) =
        refine_candidate(img, &coarse, refiner, cfg, min_angle_deg, cells_across)
    else {
        return;
    };
    if !quads.iter().any(|q| same_place(&q.corners, &c)) {
        quads.push(Quad {
            corners: c,
            contrast,
            dark_cut,
        });
    }
}
