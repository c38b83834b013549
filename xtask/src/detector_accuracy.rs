//! `cargo xtask detector-accuracy [--quick]`: measures the marker detector on synthetic scenes
//! with exact ground truth and writes `docs/detector-accuracy.md`. `--motion-blur` prints
//! only the motion-blur rows; `--sizes [FIRST_SEED]` prints only the own family against tag36h11 by
//! marker size (200 scenes, uniform light and 3:1), the check of a corner-refinement change;
//! `--paired [FIRST_SEED [PAIRS]]` prints only the paired comparison with tag36h11 (scenes
//! rendered twice from generators in the same state, once per family).
//!
//! Scenes come from `marker_testkit`, rendered by `synthcam` (seeded, so the file is reproducible): 640x480 frames
//! with 8 real markers of 20-120 px at random perspective, blur sigma 1 and noise sigma 3
//! unless a table varies one of them; marker-free clutter frames; frames of foreign markers
//! (bordered 4 x 5 codes that are not in the dictionary). The work runs in release mode: from
//! the dev profile the command re-invokes itself through `cargo run --release`. It runs on
//! every core (rayon): the accuracy and recall scenes in parallel, the standard families in
//! parallel, and the 1,000 clutter frames rendered once, in parallel, then read by every
//! detector of the false-read table and of every family (each frame seeded on its own, so
//! the figures do not depend on the number of threads).

use std::fmt::Write as _;
use std::path::PathBuf;

use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Threshold};
use marker_testkit::{
    CellPattern, MarkerScene, NotMarkers, SceneConfig, clutter_frame, marker_scene,
    marker_scene_of, motion_blur, render_scene,
};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Seed of the first clutter frame (frame `i` has its own generator, seeded `CLUTTER_SEED +
/// i`, so that the frames can be rendered in parallel).
const CLUTTER_SEED: u64 = 7_000;

/// `frames` marker-free clutter frames (640x480, blur 1, noise 3; frame `i` seeded
/// [`CLUTTER_SEED`] + `i`), rendered once, in parallel, and read by every detector of steps
/// 2 and 5 (about 300 kB a frame).
fn clutter_frames(dict: &Dictionary, frames: usize) -> crate::Result<Vec<Vec<u8>>> {
    eprintln!("detector-accuracy: rendering {frames} clutter frames");
    (0..frames as u64)
        .into_par_iter()
        .map(|i| {
            let is_entry = |code| dict.lookup_within(code, 0).is_some();
            let not_markers = NotMarkers {
                rows: dict.family().rows() as usize,
                cols: dict.family().cols() as usize,
                is_marker: &is_entry,
            };
            let mut rng = ChaCha8Rng::seed_from_u64(CLUTTER_SEED + i);
            clutter_frame(640, 480, 1.0, 3.0, not_markers, &mut rng).map_err(|e| e.to_string())
        })
        .collect::<Result<_, String>>()
        .map_err(Into::into)
}

/// Per detector, the codes it reads in all `frames` (frames in parallel, each worker with
/// its own copies of the detectors); and the quads the first detector examined.
fn reads_per_detector(dets: &[Detector], frames: &[Vec<u8>]) -> crate::Result<(Vec<usize>, usize)> {
    let n = dets.len();
    frames
        .par_iter()
        .map_init(
            || (dets.to_vec(), Vec::new()),
            |(dets, out), px| {
                let img = GrayView::new(px, 640, 480).map_err(|e| e.to_string())?;
                let mut reads = vec![0usize; n];
                let mut quads = 0;
                for (k, det) in dets.iter_mut().enumerate() {
                    let q = det.detect(&img, out);
                    if k == 0 {
                        quads = q;
                    }
                    reads[k] = out.len();
                }
                Ok::<_, String>((reads, quads))
            },
        )
        .try_reduce(
            || (vec![0usize; n], 0),
            |(mut a, qa), (b, qb)| {
                for (x, y) in a.iter_mut().zip(b) {
                    *x += y;
                }
                Ok((a, qa + qb))
            },
        )
        .map_err(Into::into)
}

/// Every entry of `dict` as a test pattern (index = dictionary index).
pub(crate) fn entries(dict: &Dictionary) -> Vec<CellPattern> {
    let f = dict.family();
    CellPattern::from_codes(
        f.rows() as usize,
        f.cols() as usize,
        (0..dict.len()).map(|i| dict.code(i).unwrap_or(0)),
    )
}

/// A foreign marker: a one-cell black border around a random code of the dictionary's
/// family that is *not* in `dictionary` (none of its entries in any orientation), with a
/// one-cell quiet zone. A detector reading it as a dictionary entry has corrected bit errors
/// that were never there; the rate of such reads is a property of the dictionary's distance
/// and the correction allowed.
fn foreign_marker<R: Rng + ?Sized>(dictionary: &Dictionary, rng: &mut R) -> CellPattern {
    let family = dictionary.family();
    loop {
        let code = rng.random_range(0..=family.mask());
        if dictionary.lookup_within(code, 0).is_none() {
            return CellPattern::from_code(family.rows() as usize, family.cols() as usize, code);
        }
    }
}

const USAGE: &str = "usage: cargo xtask detector-accuracy [--quick | --motion-blur [FIRST_SEED [SCENES]] | --sizes [FIRST_SEED] | --paired [FIRST_SEED [SCENES]]]";

/// Pairs of scenes of the paired comparison with tag36h11 (one marker each).
const PAIRED_SCENES: usize = 2000;

fn target() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("docs/detector-accuracy.md")
}

/// What `run` was asked for.
enum Mode {
    /// The document (`quick`: fewer scenes).
    Document { quick: bool },
    /// Only the motion-blur rows, printed: first seed, scenes per row.
    MotionBlur(u64, usize),
    /// Only the by-size table, printed, from this first seed.
    Sizes(u64),
    /// Only the paired comparison with tag36h11, printed: first seed, pairs of scenes.
    Paired(u64, usize),
}

pub fn run(args: &[String]) -> crate::Result {
    let mode = match args {
        [] => Mode::Document { quick: false },
        [flag] if flag == "--quick" => Mode::Document { quick: true },
        [flag] if flag == "--motion-blur" => Mode::MotionBlur(MOTION_BLUR_SEED, 10),
        [flag, first] if flag == "--motion-blur" => {
            Mode::MotionBlur(first.parse().map_err(|_| USAGE)?, 10)
        }
        [flag, first, scenes] if flag == "--motion-blur" => Mode::MotionBlur(
            first.parse().map_err(|_| USAGE)?,
            scenes.parse().map_err(|_| USAGE)?,
        ),
        [flag] if flag == "--sizes" => Mode::Sizes(0),
        [flag] if flag == "--paired" => Mode::Paired(PAIRED_SEED, PAIRED_SCENES),
        [flag, first] if flag == "--paired" => {
            Mode::Paired(first.parse().map_err(|_| USAGE)?, PAIRED_SCENES)
        }
        [flag, first, scenes] if flag == "--paired" => Mode::Paired(
            first.parse().map_err(|_| USAGE)?,
            scenes.parse().map_err(|_| USAGE)?,
        ),
        [flag, first] if flag == "--sizes" => Mode::Sizes(first.parse().map_err(|_| USAGE)?),
        _ => return Err(USAGE.into()),
    };
    if cfg!(debug_assertions) && std::env::var_os("XTASK_DETECTOR_ACCURACY_RELEASE").is_none() {
        return crate::release::rerun_in_release(
            "detector-accuracy",
            args,
            "XTASK_DETECTOR_ACCURACY_RELEASE",
        );
    }
    let quick = match mode {
        Mode::Document { quick } => quick,
        Mode::Sizes(first) => return size_tables(200, first),
        Mode::Paired(first, scenes) => {
            let mut doc = String::new();
            paired_rows(&mut doc, &paired_bins(scenes, first)?)?;
            print!("{doc}");
            return Ok(());
        }
        Mode::MotionBlur(first, scenes) => {
            // Only the motion-blur rows, printed (the document is not written).
            let mut doc = String::new();
            motion_blur_rows(&mut doc, &entries(Dictionary::paper()), first, scenes)?;
            print!("{doc}");
            return Ok(());
        }
    };
    let n = |full: usize, q: usize| if quick { q } else { full };
    let dict = Dictionary::paper();
    let all = entries(dict);
    let mut doc = header(quick)?;
    let (by_errors, otsu) = accuracy_scenes(&mut doc, &all, n(200, 20))?;
    let clutter = clutter_frames(dict, n(1000, 100))?;
    let clutter_reads = false_reads(&mut doc, dict, &by_errors, &clutter, n(100, 10))?;
    recall_curves(&mut doc, &all, n(50, 8))?;
    family_rows(&mut doc, &by_errors[0].2, n(50, 4), &clutter)?;
    motion_blur_rows(&mut doc, &all, MOTION_BLUR_SEED, n(10, 3))?;
    writeln!(
        doc,
        "Otsu on the accuracy scenes: recall {:.2} %, corner RMS {:.4} px, wrong codes {}.",
        otsu.recall(),
        otsu.rms(),
        otsu.wrong
    )?;
    let path = target();
    std::fs::write(&path, doc)?;
    let def = &by_errors[0].2;
    println!(
        "detector-accuracy: wrote {} (found {}/{}, corner RMS {:.4} px, clutter reads {})",
        path.display(),
        def.found,
        def.total,
        def.rms(),
        clutter_reads
    );
    Ok(())
}

/// The document's title and preamble.
fn header(quick: bool) -> Result<String, std::fmt::Error> {
    let mut doc = String::new();
    writeln!(doc, "# Detector accuracy\n")?;
    writeln!(
        doc,
        "Generated by `cargo xtask detector-accuracy`{} from seeded synthetic scenes \
         (`marker_testkit`, rendered by `synthcam`): do not edit by hand. Corner errors are against the exact \
         ground truth of the warp, in the marker's own corner order (NW, NE, SE, SW), \
         pixel-centre convention. A marker counts as found only if it is read with its own \
         dictionary index; any other read is a wrong code.\n",
        if quick { " --quick" } else { "" }
    )?;
    Ok(doc)
}

/// The decoding variants' tallies on the accuracy scenes, and Otsu's.
type VariantTallies = Vec<(String, DetectorConfig, Tally)>;

/// Step 1: `scenes` accuracy scenes, every decoding variant and Otsu; writes their table.
fn accuracy_scenes(
    doc: &mut String,
    all: &[CellPattern],
    scenes: usize,
) -> crate::Result<(VariantTallies, Tally)> {
    eprintln!("detector-accuracy: {scenes} accuracy scenes");
    let base = SceneConfig::default();
    let variants = variants();
    let mut configs: Vec<DetectorConfig> = variants.iter().map(|(_, cfg)| *cfg).collect();
    configs.push(DetectorConfig {
        threshold: Threshold::Otsu,
        ..DetectorConfig::default()
    });
    // Scenes in parallel, one tally per configuration (the last is Otsu).
    let mut tallies = par_tallies(scenes, &configs, |seed| {
        marker_scene(&base, all, &mut ChaCha8Rng::seed_from_u64(seed))
    })?;
    let otsu = tallies.pop().unwrap_or_default();
    let by_errors: Vec<(String, DetectorConfig, Tally)> = variants
        .into_iter()
        .zip(tallies)
        .map(|((label, cfg), t)| (label, cfg, t))
        .collect();
    let def = &by_errors[0].2;
    writeln!(doc, "## Accuracy scenes\n")?;
    writeln!(
        doc,
        "{scenes} scenes of 640x480, 8 markers each (longer side 20-120 px, random rotation \
         and perspective), blur sigma 1, noise sigma 3, default detector (adaptive \
         threshold, soft-decision correction of up to 2 weak cells, no hard correction).\n"
    )?;
    writeln!(doc, "| figure | value |\n| --- | --- |")?;
    writeln!(
        doc,
        "| markers found | {} / {} ({:.2} %) |",
        def.found,
        def.total,
        100.0 * def.found as f64 / def.total.max(1) as f64
    )?;
    writeln!(
        doc,
        "| scenes with all 8 found | {} / {} ({:.1} %) |",
        def.complete,
        def.scenes,
        100.0 * def.complete as f64 / def.scenes.max(1) as f64
    )?;
    writeln!(doc, "| wrong codes | {} |", def.wrong)?;
    writeln!(doc, "| corner RMS error | {:.4} px |", def.rms())?;
    writeln!(doc, "| largest corner error | {:.3} px |", def.max_err)?;
    writeln!(doc, "\nCorner RMS by marker size (longer side):\n")?;
    writeln!(
        doc,
        "| side (px) | markers | corner RMS (px) |\n| --- | --- | --- |"
    )?;
    for (i, (se, count)) in def.by_size.iter().enumerate() {
        if *count > 0 {
            writeln!(
                doc,
                "| {}-{} | {} | {:.4} |",
                20 + 20 * i,
                40 + 20 * i,
                count,
                (se / (4 * count) as f64).sqrt()
            )?;
        }
    }
    Ok((by_errors, otsu))
}

/// Steps 2 and 3: `frames` marker-free clutter frames and `foreign_scenes` scenes of foreign
/// markers, every decoding variant; writes their table. Returns the default detector's
/// reads in clutter.
fn false_reads(
    doc: &mut String,
    dict: &Dictionary,
    by_errors: &VariantTallies,
    clutter_px: &[Vec<u8>],
    foreign_scenes: usize,
) -> crate::Result<usize> {
    let base = SceneConfig::default();
    let frames = clutter_px.len();
    eprintln!("detector-accuracy: {frames} clutter frames");
    let nv = by_errors.len();
    let mut dets: Vec<Detector> = by_errors
        .iter()
        .map(|(_, cfg, _)| Detector::new(*cfg))
        .collect();
    dets.push(Detector::new(DetectorConfig {
        threshold: Threshold::Otsu,
        ..DetectorConfig::default()
    }));
    // Each variant, then Otsu.
    let (clutter, quads) = reads_per_detector(&dets, clutter_px)?;
    let mut out = Vec::new();
    // Foreign markers.
    eprintln!("detector-accuracy: {foreign_scenes} foreign-marker scenes");
    let mut foreign = vec![0usize; nv];
    let mut foreign_total = 0;
    for seed in 0..foreign_scenes as u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(9_000 + seed);
        let patterns: Vec<CellPattern> = (0..8).map(|_| foreign_marker(dict, &mut rng)).collect();
        let scene = render_scene(&base, &patterns, &mut rng)?;
        foreign_total += scene.markers.len();
        let img = GrayView::new(&scene.pixels, scene.width, scene.height)?;
        for (k, det) in dets.iter_mut().take(nv).enumerate() {
            det.detect(&img, &mut out);
            foreign[k] += out.len();
        }
    }
    writeln!(doc, "\n## False reads and bit correction\n")?;
    writeln!(
        doc,
        "{frames} marker-free clutter frames of 640x480 (textured background, rectangles, \
         black-bordered squares with random insides of random grid size, redrawn when one is \
         by chance a dictionary entry, checkers, text-like strokes; blur 1, noise 3) offered the default detector {quads} quads. \
         Foreign markers: {foreign_total} bordered 4 x 5 codes that are in no orientation a \
         dictionary entry, in {foreign_scenes} accuracy-style scenes. The recall column is \
         from the accuracy scenes above.\n"
    )?;
    writeln!(
        doc,
        "| bit correction | recall | wrong codes in accuracy scenes | \
         codes read in clutter | foreign markers read |\n| --- | --- | --- | --- | --- |"
    )?;
    for (k, (label, _, t)) in by_errors.iter().enumerate() {
        writeln!(
            doc,
            "| {label} | {:.2} % | {} | {} | {} / {} |",
            100.0 * t.found as f64 / t.total.max(1) as f64,
            t.wrong,
            clutter[k],
            foreign[k],
            foreign_total
        )?;
    }
    writeln!(
        doc,
        "\nSoft decision (`decode.soft_errors`, `decode.soft_margin`): a reading that is no \
         entry may have up to that many of its least confident cells flipped, each only if \
         its level is within that fraction of half the contrast from the threshold; the \
         flipped code must then be an entry exactly. Hard correction (`decode.max_errors`) \
         accepts any entry within that many bits.\n\nWith the Otsu threshold (default \
         decoding): {} codes read in clutter.",
        clutter[nv]
    )?;
    Ok(clutter[0])
}

/// Step 4: recall and corner RMS against lighting, noise and blur, `per` scenes a row.
fn recall_curves(doc: &mut String, all: &[CellPattern], per: usize) -> crate::Result {
    let base = SceneConfig::default();
    writeln!(doc, "\n## Recall under lighting, noise and blur\n")?;
    writeln!(
        doc,
        "{per} scenes (8 markers each) per row; otherwise as the accuracy scenes. Lighting \
         falls linearly across the frame from 1 to 1/ratio. Adaptive is the default \
         threshold, Otsu the paper's global one.\n"
    )?;
    let curves: [(&str, Vec<(String, SceneConfig)>); 3] = [
        (
            "lighting ratio",
            [1.0, 2.0, 3.0, 4.0]
                .iter()
                .map(|&r| {
                    (
                        format!("{r}:1"),
                        SceneConfig {
                            lighting: r,
                            ..base
                        },
                    )
                })
                .collect(),
        ),
        (
            "noise sigma",
            [0.0, 3.0, 5.0, 7.5, 10.0]
                .iter()
                .map(|&s| (format!("{s}"), SceneConfig { noise: s, ..base }))
                .collect(),
        ),
        (
            "blur sigma",
            [0.0, 0.5, 1.0, 1.5, 2.0]
                .iter()
                .map(|&s| (format!("{s}"), SceneConfig { blur: s, ..base }))
                .collect(),
        ),
    ];
    for (name, rows) in curves {
        eprintln!("detector-accuracy: recall against {name}");
        writeln!(
            doc,
            "| {name} | adaptive recall | adaptive corner RMS (px) | Otsu recall | Otsu corner RMS (px) | wrong codes (both) |\n| --- | --- | --- | --- | --- | --- |"
        )?;
        for (label, cfg) in rows {
            let configs = [
                DetectorConfig::default(),
                DetectorConfig {
                    threshold: Threshold::Otsu,
                    ..DetectorConfig::default()
                },
            ];
            let mut t = par_tallies(per, &configs, |seed| {
                marker_scene(&cfg, all, &mut ChaCha8Rng::seed_from_u64(50_000 + seed))
            })?;
            let (o, a) = (t.pop().unwrap_or_default(), t.pop().unwrap_or_default());
            writeln!(
                doc,
                "| {label} | {:.1} % | {:.4} | {:.1} % | {:.4} | {} |",
                a.recall(),
                a.rms(),
                o.recall(),
                o.rms(),
                a.wrong + o.wrong
            )?;
        }
        writeln!(doc)?;
    }
    Ok(())
}

/// The rows of the own-against-tag36h11 table by marker size: count and corner RMS with one
/// standard error (RMS / sqrt(2 x corners)) per bin.
fn size_rows(doc: &mut String, own: &Tally, tag_tally: &Tally) -> crate::Result {
    for i in 0..6 {
        let (oe, on) = own.by_size[i];
        let (te, tn) = tag_tally.by_size[i];
        if on + tn > 0 {
            let rms = |e: f64, n: usize| (e / (4 * n.max(1)) as f64).sqrt();
            let se = |e: f64, n: usize| rms(e, n) / ((8 * n.max(1)) as f64).sqrt();
            writeln!(
                doc,
                "| {}-{} | {on} | {:.4} +- {:.4} | {tn} | {:.4} +- {:.4} |",
                20 + 20 * i,
                40 + 20 * i,
                rms(oe, on),
                se(oe, on),
                rms(te, tn),
                se(te, tn)
            )?;
        }
    }
    Ok(())
}

/// tag36h11 markers read by a tag36h11 detector on `scenes` scenes of `cfg` seeded
/// `seed0 + i` (the seeds of the own family's scenes, codes drawn from another list).
fn tag36h11_tally(scenes: usize, cfg: &SceneConfig, seed0: u64) -> crate::Result<Tally> {
    let tag = fiducial::dictionary_by_name("tag36h11")?.clone();
    let n = tag.family().rows() as usize;
    let tag_all = CellPattern::from_codes(n, n, tag.codes().iter().copied());
    let detector = Detector::with_dictionary(DetectorConfig::default(), tag);
    Ok(par_tallies_with(scenes, &[detector], |seed| {
        marker_scene(cfg, &tag_all, &mut ChaCha8Rng::seed_from_u64(seed0 + seed))
    })?
    .pop()
    .unwrap_or_default())
}

/// The longer side of a placed marker, pixels.
fn longer(m: &marker_testkit::PlacedMarker) -> f64 {
    (0..4)
        .map(|k| (m.corners[(k + 1) % 4] - m.corners[k]).norm())
        .fold(0.0, f64::max)
}

/// The by-size tables' bin of a placed marker: 20 px wide from 20 px on, the last one open.
fn size_bin(m: &marker_testkit::PlacedMarker) -> usize {
    (((longer(m) - 20.0) / 20.0).max(0.0) as usize).min(5)
}

/// Seeds of the paired comparison's scenes (new ones: not those of any other table).
const PAIRED_SEED: u64 = 900_000;

/// Per size bin of the paired comparison: pairs, and sums of the own and tag36h11 markers'
/// mean squared corner errors and of their difference squared.
#[derive(Default, Clone, Copy)]
struct PairBin {
    n: usize,
    own: f64,
    tag: f64,
    d2: f64,
}

/// Each marker's mean squared corner error in `scene` as `detector` reads it (`None` where
/// it is not read).
fn marker_errors(scene: &MarkerScene, detector: &mut Detector) -> crate::Result<Vec<Option<f64>>> {
    let img = GrayView::new(&scene.pixels, scene.width, scene.height)?;
    let mut out = Vec::new();
    detector.detect(&img, &mut out);
    Ok(scene
        .markers
        .iter()
        .map(|m| {
            let d = out.iter().find(|d| Some(d.index) == m.index)?;
            Some(
                (0..4)
                    .map(|i| (d.corners[i] - m.corners[i]).norm_squared())
                    .sum::<f64>()
                    / 4.0,
            )
        })
        .collect())
}

/// The paired comparison of tag36h11 with the own family: `scenes` pairs of scenes
/// (seeded `first + i`), each pair rendered from generators in the same state (the same
/// placement, perspective, blur and noise), one with an own marker and one with a tag36h11
/// marker (chosen by a generator of their own); a pair counts when its markers have the same
/// centre and longer side (the placement may be redrawn where one shape does not fit) and
/// both are read, binned by the longer side.
fn paired_bins(scenes: usize, first: u64) -> crate::Result<[PairBin; 6]> {
    let own_entries = entries(Dictionary::paper());
    let tag = fiducial::dictionary_by_name("tag36h11")?.clone();
    let n = tag.family().rows() as usize;
    let tag_entries = CellPattern::from_codes(n, n, tag.codes().iter().copied());
    let own_det = Detector::new(DetectorConfig::default());
    let tag_det = Detector::with_dictionary(DetectorConfig::default(), tag);
    // One marker a scene: a later marker's placement depends on where the earlier ones fit,
    // which differs between the families' shapes, so only the first is paired reliably.
    let cfg = SceneConfig {
        markers: 1,
        ..SceneConfig::default()
    };
    let pick = |rng: &mut ChaCha8Rng, len: usize| vec![rng.random_range(0..len)];
    (0..scenes as u64)
        .into_par_iter()
        .map_init(
            || (own_det.clone(), tag_det.clone()),
            |(od, td), i| {
                let seed = first + i;
                let mut codes = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_c0de);
                let (oi, ti) = (
                    pick(&mut codes, own_entries.len()),
                    pick(&mut codes, tag_entries.len()),
                );
                let render = |e: &[CellPattern], idx: &[usize]| {
                    marker_scene_of(&cfg, e, idx, &mut ChaCha8Rng::seed_from_u64(seed))
                        .map_err(|e| e.to_string())
                };
                let (os, ts) = (render(&own_entries, &oi)?, render(&tag_entries, &ti)?);
                let (oe, te) = (
                    marker_errors(&os, od).map_err(|e| e.to_string())?,
                    marker_errors(&ts, td).map_err(|e| e.to_string())?,
                );
                // A placement's two markers: about the same centre and longer side (the
                // shapes differ, so perspective moves them a little differently; where one
                // does not fit, the placement is redrawn somewhere else entirely).
                let centre = |m: &marker_testkit::PlacedMarker| {
                    m.corners
                        .iter()
                        .fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords)
                        / 4.0
                };
                let mut bins = [PairBin::default(); 6];
                for (m, o) in os.markers.iter().zip(oe) {
                    let Some(o) = o else {
                        continue;
                    };
                    let Some(t) = ts.markers.iter().zip(&te).find_map(|(n, t)| {
                        ((centre(n) - centre(m)).norm() < 5.0
                            && (longer(n) / longer(m) - 1.0).abs() < 0.1)
                            .then_some(*t)
                            .flatten()
                    }) else {
                        continue;
                    };
                    let b = &mut bins[size_bin(m)];
                    b.n += 1;
                    b.own += o;
                    b.tag += t;
                    b.d2 += (t - o) * (t - o);
                }
                Ok::<_, String>(bins)
            },
        )
        .try_reduce(
            || [PairBin::default(); 6],
            |mut a, b| {
                for (x, y) in a.iter_mut().zip(b) {
                    x.n += y.n;
                    x.own += y.own;
                    x.tag += y.tag;
                    x.d2 += y.d2;
                }
                Ok(a)
            },
        )
        .map_err(Into::into)
}

/// The paired comparison's table: per bin, pairs, each family's corner RMS, and the ratio of
/// tag36h11's mean squared corner error to the own family's with one standard error (from
/// the spread of the pairs' differences).
fn paired_rows(doc: &mut String, bins: &[PairBin; 6]) -> crate::Result {
    writeln!(
        doc,
        "| side (px) | pairs | own RMS (px) | tag36h11 RMS (px) | tag36h11 / own mean squared error |\n| --- | --- | --- | --- | --- |"
    )?;
    for (i, b) in bins.iter().enumerate() {
        if b.n == 0 {
            continue;
        }
        let n = b.n as f64;
        let (mo, mt) = (b.own / n, b.tag / n);
        let d = mt - mo;
        // Standard error of the mean difference, then of the ratio (the own mean taken as
        // exact beside it).
        let var = (b.d2 / n - d * d).max(0.0) * n / (n - 1.0).max(1.0);
        let se = (var / n).sqrt() / mo;
        writeln!(
            doc,
            "| {}-{} | {} | {:.4} | {:.4} | {:.3} +- {:.3} |",
            20 + 20 * i,
            40 + 20 * i,
            b.n,
            mo.sqrt(),
            mt.sqrt(),
            mt / mo,
            se
        )?;
    }
    Ok(())
}

/// `--sizes [FIRST_SEED]`: the own family against tag36h11 by marker size, `scenes` scenes
/// each, under uniform light (the accuracy scenes' seeds, or `first` on) and under a 3:1
/// light ratio (the lighting rows' seeds, or `first + 50,000` on), printed; a quick check of
/// a corner-refinement change, and with another `first`, of it on seeds it was not tuned on.
fn size_tables(scenes: usize, first: u64) -> crate::Result {
    let all = entries(Dictionary::paper());
    let mut doc = String::new();
    for (label, cfg, seed0) in [
        ("uniform light", SceneConfig::default(), first),
        (
            "lighting 3:1",
            SceneConfig {
                lighting: 3.0,
                ..SceneConfig::default()
            },
            first + 50_000,
        ),
    ] {
        eprintln!("detector-accuracy: sizes, {label}");
        let own = par_tallies(scenes, &[DetectorConfig::default()], |seed| {
            marker_scene(&cfg, &all, &mut ChaCha8Rng::seed_from_u64(seed0 + seed))
        })?
        .pop()
        .unwrap_or_default();
        let tag = tag36h11_tally(scenes, &cfg, seed0)?;
        writeln!(
            doc,
            "{label}, {scenes} scenes from seed {seed0}: own RMS {:.4} (recall {:.2} %), tag36h11 RMS {:.4} (recall {:.2} %)\n\n| side (px) | own markers | own RMS (px) | tag36h11 markers | tag36h11 RMS (px) |\n| --- | --- | --- | --- | --- |",
            own.rms(),
            own.recall(),
            tag.rms(),
            tag.recall()
        )?;
        size_rows(&mut doc, &own, &tag)?;
        writeln!(doc)?;
    }
    print!("{doc}");
    Ok(())
}

/// First seed of the document's motion-blur scenes.
const MOTION_BLUR_SEED: u64 = 70_000;

/// Motion blur lengths of the motion-blur rows, pixels.
const MOTION_BLUR_LENGTHS: [f64; 4] = [3.0, 5.0, 9.0, 13.0];

/// The motion-blur rows (issue #16): `per` scenes per length of eight markers with borders
/// of 20-70 px, blur sigma 1 and noise sigma 3, then a box motion blur of that length in a
/// random direction per scene (`marker_testkit::motion_blur`), read by the default detector.
/// Scenes are seeded from `first_seed`.
fn motion_blur_rows(
    doc: &mut String,
    all: &[CellPattern],
    first_seed: u64,
    per: usize,
) -> crate::Result {
    eprintln!("detector-accuracy: motion blur");
    writeln!(doc, "\n## Motion blur\n")?;
    writeln!(
        doc,
        "{per} scenes per row of 8 markers with borders of 20-70 px (so {} markers a row), blur \
         sigma 1, noise sigma 3, then a box motion blur of the given length in a random \
         direction per scene (the camera moving while the shutter is open; the blur is \
         centred, so the true corners do not move). Our dictionary, read without \
         `DetectorConfig::motion_blur` (the plain reading) and by the default detector, \
         which has it on (a quad with a marker's border whose cells are not an entry, and \
         whose edges show a motion of at least 1.5 cells, is read again with its cell \
         levels solved for that motion, and when that matches no entry, as the entry whose \
         differing cells have the least summed margin, if its outline is smeared outwards \
         and no other entry comes close; dark regions up to 160 px that gave no quad are \
         also cut nearer the white level, where a smeared outline is closed). The \
         peers' figures of issue #16 (OpenCV-made scenes, horizontal blur, each detector with \
         its own markers in the same placements) were, at 5 px: AprilTag 3 66/80, OpenCV \
         ArUco 63/80; at 9 px: AprilTag 3 41/80, OpenCV ArUco 49/80. They are quoted, not \
         rerun here.\n",
        8 * per
    )?;
    writeln!(
        doc,
        "| motion blur (px) | plain reading: markers read | recall | corner RMS (px) | wrong codes | default (`motion_blur` on): markers read | its corner RMS (px) | its wrong codes |\n| --- | --- | --- | --- | --- | --- | --- | --- |"
    )?;
    let base = SceneConfig {
        min_side: 20.0,
        max_side: 70.0,
        ..SceneConfig::default()
    };
    for length in MOTION_BLUR_LENGTHS {
        let (mut t, mut b) = (Tally::default(), Tally::default());
        for seed in 0..per as u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(first_seed + seed);
            let mut scene = marker_scene(&base, all, &mut rng)?;
            let angle = rng.random_range(0.0..std::f64::consts::PI);
            scene.pixels = motion_blur(&scene.pixels, scene.width, scene.height, length, angle)?;
            t.add(
                &scene,
                DetectorConfig {
                    motion_blur: false,
                    ..DetectorConfig::default()
                },
            )?;
            b.add(&scene, DetectorConfig::default())?;
        }
        writeln!(
            doc,
            "| {length} | {} / {} | {:.1} % | {:.4} | {} | {} / {} | {:.4} | {} |",
            t.found,
            t.total,
            t.recall(),
            t.rms(),
            t.wrong,
            b.found,
            b.total,
            b.rms(),
            b.wrong
        )?;
    }
    Ok(())
}

/// The decoding variants compared: the default first.
fn variants() -> Vec<(String, DetectorConfig)> {
    let with = |soft: u32, hard: u32| {
        let mut cfg = DetectorConfig::default();
        cfg.decode.soft_errors = soft;
        cfg.decode.max_errors = hard;
        cfg
    };
    let def = DetectorConfig::default();
    vec![
        (
            format!(
                "soft {} cells, margin < {}, hard {} (default)",
                def.decode.soft_errors, def.decode.soft_margin, def.decode.max_errors
            ),
            def,
        ),
        ("none".into(), with(0, 0)),
        (
            format!("soft 1 cell, margin < {}", def.decode.soft_margin),
            with(1, 0),
        ),
        ("hard 1 bit".into(), with(0, 1)),
        ("hard 2 bits".into(), with(0, 2)),
    ]
}

/// Tallies of every configuration of `configs` (our own dictionary) over the scenes
/// `scene(seed)` for seeds `0..scenes`: [`par_tallies_with`] their detectors.
fn par_tallies(
    scenes: usize,
    configs: &[DetectorConfig],
    scene: impl Fn(u64) -> Result<MarkerScene, marker_testkit::TestkitError> + Sync,
) -> crate::Result<Vec<Tally>> {
    let detectors: Vec<Detector> = configs.iter().map(|c| Detector::new(*c)).collect();
    par_tallies_with(scenes, &detectors, scene)
}

/// Tallies of every detector of `detectors` over the scenes `scene(seed)` for seeds
/// `0..scenes` (scenes rendered and read in parallel; each worker reads with its own copies
/// of the detectors).
fn par_tallies_with(
    scenes: usize,
    detectors: &[Detector],
    scene: impl Fn(u64) -> Result<MarkerScene, marker_testkit::TestkitError> + Sync,
) -> crate::Result<Vec<Tally>> {
    let n = detectors.len();
    let empty = || (0..n).map(|_| Tally::default()).collect::<Vec<_>>();
    (0..scenes as u64)
        .into_par_iter()
        .map_init(
            || detectors.to_vec(),
            |dets, seed| {
                let scene = scene(seed).map_err(|e| e.to_string())?;
                let mut t = empty();
                for (tally, det) in t.iter_mut().zip(dets.iter_mut()) {
                    tally.add_with(&scene, det).map_err(|e| e.to_string())?;
                }
                Ok::<_, String>(t)
            },
        )
        .try_reduce(empty, |a, b| {
            Ok(a.into_iter().zip(b).map(|(x, y)| x.merge(y)).collect())
        })
        .map_err(Into::into)
}

/// Running totals over scenes.
#[derive(Default)]
struct Tally {
    scenes: usize,
    complete: usize,
    total: usize,
    found: usize,
    wrong: usize,
    sq_err: f64,
    corners: usize,
    max_err: f64,
    by_size: [(f64, usize); 6],
}

impl Tally {
    fn add(&mut self, scene: &MarkerScene, cfg: DetectorConfig) -> crate::Result {
        self.add_with(scene, &mut Detector::new(cfg))
    }

    fn add_with(&mut self, scene: &MarkerScene, det: &mut Detector) -> crate::Result {
        let img = GrayView::new(&scene.pixels, scene.width, scene.height)?;
        let mut out = Vec::new();
        det.detect(&img, &mut out);
        self.scenes += 1;
        let mut found_here = 0;
        for m in &scene.markers {
            self.total += 1;
            let Some(d) = out.iter().find(|d| Some(d.index) == m.index) else {
                continue;
            };
            found_here += 1;
            self.found += 1;
            let mut se = 0.0;
            for i in 0..4 {
                let e = (d.corners[i] - m.corners[i]).norm();
                se += e * e;
                self.max_err = self.max_err.max(e);
            }
            self.sq_err += se;
            self.corners += 4;
            let bin = size_bin(m);
            self.by_size[bin].0 += se;
            self.by_size[bin].1 += 1;
        }
        self.wrong += out
            .iter()
            .filter(|d| !scene.markers.iter().any(|m| m.index == Some(d.index)))
            .count();
        if found_here == scene.markers.len() {
            self.complete += 1;
        }
        Ok(())
    }

    fn rms(&self) -> f64 {
        (self.sq_err / self.corners.max(1) as f64).sqrt()
    }

    /// Adds the counts of `o` (scenes tallied apart, e.g. on another thread).
    fn merge(mut self, o: Tally) -> Tally {
        self.scenes += o.scenes;
        self.complete += o.complete;
        self.total += o.total;
        self.found += o.found;
        self.wrong += o.wrong;
        self.sq_err += o.sq_err;
        self.corners += o.corners;
        self.max_err = self.max_err.max(o.max_err);
        for (a, b) in self.by_size.iter_mut().zip(o.by_size) {
            a.0 += b.0;
            a.1 += b.1;
        }
        self
    }

    fn recall(&self) -> f64 {
        100.0 * self.found as f64 / self.total.max(1) as f64
    }
}

/// One family's row of step 5 (before its clutter reads).
struct FamilyRow {
    sd: &'static fiducial::StandardDictionary,
    correction: u32,
    fixtures_ok: usize,
    fixtures: usize,
    tally: Tally,
    detector: Detector,
}

/// One family of step 5: its OpenCV-drawn fixtures and `scenes` synthetic scenes.
fn family_row(
    sd: &'static fiducial::StandardDictionary,
    scenes: usize,
) -> crate::Result<FamilyRow> {
    let base = SceneConfig::default();
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/markers");
    let dict = fiducial::dictionary_by_name(sd.name)?;
    let mut det = Detector::with_dictionary(DetectorConfig::default(), dict.clone());
    // OpenCV's own drawings.
    let (mut fx_ok, mut fx_total) = (0, 0);
    for entry in std::fs::read_dir(fixtures.join(sd.name))? {
        let path = entry?.path();
        let id: usize = path
            .file_stem()
            .and_then(|s| s.to_str())
            .ok_or("bad fixture name")?
            .parse()?;
        let img = image::open(&path)?.to_luma8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let m = w / 4;
        let cw = w + 2 * m;
        let mut canvas = vec![255u8; cw * (h + 2 * m)];
        for y in 0..h {
            canvas[(y + m) * cw + m..(y + m) * cw + m + w]
                .copy_from_slice(&img.as_raw()[y * w..(y + 1) * w]);
        }
        let mut out = Vec::new();
        det.detect(&GrayView::new(&canvas, cw, h + 2 * m)?, &mut out);
        fx_total += 1;
        let same = |i: usize| {
            (0..4u8)
                .any(|q| dict.family().rotate(dict.codes()[i], q).ok() == Some(dict.codes()[id]))
        };
        if out.len() == 1 && (out[0].index == id || same(out[0].index)) {
            fx_ok += 1;
        }
    }
    // Synthetic scenes.
    let n = sd.size as usize;
    let all = CellPattern::from_codes(n, n, dict.codes().iter().copied());
    let mut tally = Tally::default();
    for seed in 0..scenes as u64 {
        let scene = marker_scene(&base, &all, &mut ChaCha8Rng::seed_from_u64(50_000 + seed))?;
        tally.add_with(&scene, &mut det)?;
    }
    Ok(FamilyRow {
        sd,
        correction: dict.max_correctable(),
        fixtures_ok: fx_ok,
        fixtures: fx_total,
        tally,
        detector: det,
    })
}

/// Step 5: every predefined (OpenCV/AprilTag) dictionary with the default detector: its
/// OpenCV-drawn fixtures (`fixtures/markers/`, on a white margin), `scenes` accuracy scenes
/// of its own markers (seeds 50,000 on, never tuned on), and each family's reads in
/// `frames` clutter frames (the same frames for every family).
fn family_rows(
    doc: &mut String,
    own: &Tally,
    scenes: usize,
    clutter_px: &[Vec<u8>],
) -> crate::Result {
    let frames = clutter_px.len();
    eprintln!(
        "detector-accuracy: {} families",
        fiducial::standard_dictionaries().len()
    );
    // Families in parallel (their fixtures and scenes), then the clutter frames in parallel.
    let rows: Vec<FamilyRow> = fiducial::standard_dictionaries()
        .par_iter()
        .map(|sd| family_row(sd, scenes).map_err(|e| format!("{}: {e}", sd.name)))
        .collect::<Result<_, String>>()?;
    let dets: Vec<Detector> = rows.iter().map(|r| r.detector.clone()).collect();
    let (clutter, _) = reads_per_detector(&dets, clutter_px)?;
    let rows: Vec<_> = rows
        .into_iter()
        .map(|r| (r.sd, r.correction, r.fixtures_ok, r.fixtures, r.tally))
        .collect();
    writeln!(doc, "\n## Standard families\n")?;
    writeln!(
        doc,
        "Every predefined OpenCV dictionary with the default detector (soft decisions up to \
         the family's correction, no hard correction; white reference from the marker's own \
         cells). *Fixtures*: OpenCV-drawn markers of `fixtures/markers/` read with the right \
         id. *Scenes*: {scenes} accuracy scenes per family (as above: 8 markers of 20-120 px, \
         blur 1, noise 3; seeds 50,000 on). *Clutter*: codes read in the same {frames} \
         clutter frames as above (black-bordered squares of every grid size with random \
         insides: a 4 x 4 square is an exact `DICT_4X4_1000` entry with probability 6 %, so \
         small, dense families read clutter however they are decoded). `correction` is the \
         number of bits the family corrects, OpenCV's default (`maxCorrectionBits` x 0.6).\n"
    )?;
    writeln!(
        doc,
        "| dictionary | ids | d_min | correction | fixtures | markers found | wrong ids | \
         corner RMS (px) | clutter reads |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )?;
    writeln!(
        doc,
        "| FORMATION_4X5 (own, above) | 100 | 6 | 2 | - | {} / {} ({:.2} %) | {} | {:.4} | see above |",
        own.found,
        own.total,
        own.recall(),
        own.wrong,
        own.rms()
    )?;
    for ((sd, corr, fx_ok, fx_total, t), reads) in rows.iter().zip(&clutter) {
        writeln!(
            doc,
            "| {} | {} | {} | {} | {fx_ok} / {fx_total} | {} / {} ({:.2} %) | {} | {:.4} | {reads} |",
            sd.name,
            sd.len,
            sd.min_distance,
            corr,
            t.found,
            t.total,
            t.recall(),
            t.wrong,
            t.rms()
        )?;
    }
    // tag36h11 against our own family, by marker size: on the own accuracy scenes' seeds,
    // count and settings (the 50 scenes of the family row leave 12-60 markers in the
    // larger size bins, where the RMS is uncertain by 5-10 %).
    let tag_tally = tag36h11_tally(own.scenes, &SceneConfig::default(), 0)?;
    writeln!(
        doc,
        "
tag36h11 against our own family by marker size (longer side): the {} accuracy \
         scenes above, and {} scenes of the same seeds and settings (sizes 20-120 px, blur 1, \
         noise 3; the codes are drawn from another list, so the placements differ) with \
         tag36h11 markers read by a tag36h11 detector. `+-` is one standard error of the RMS \
         (RMS / sqrt(2 x corners)).\n\n| side (px) | own markers | own RMS (px) | tag36h11 \
         markers | tag36h11 RMS (px) |\n| --- | --- | --- | --- | --- |",
        own.scenes, tag_tally.scenes
    )?;
    size_rows(doc, own, &tag_tally)?;
    eprintln!("detector-accuracy: {PAIRED_SCENES} pairs of scenes, own family and tag36h11");
    let bins = paired_bins(PAIRED_SCENES, PAIRED_SEED)?;
    writeln!(
        doc,
        "
The same comparison paired, which takes the placements' spread out of it: {PAIRED_SCENES} \
         pairs of 640x480 scenes (seeds {PAIRED_SEED} on, used by no other table), the two \
         scenes of a pair rendered from generators in the same state (the same placement, \
         perspective, blur 1 and noise 3), one with an own marker and one with a tag36h11 \
         marker (drawn apart). The own markers are 6 x 7 cells, so at the same longer side \
         their shorter side is 6/7 of the tag's and their cells are 8/7 as wide. A pair \
         counts when its two markers have about the same centre and longer side (within 5 px \
         and 10 %: where one shape does not fit, the placement is redrawn elsewhere and the \
         pair is lost) and both are read; bins by the own marker's longer side. The last column is tag36h11's mean squared corner error over the \
         own family's on the same placements, with one standard error from the spread of the \
         pairs' differences: under 1, tag36h11 markers are located more accurately. \
         `cargo xtask detector-accuracy --paired [FIRST_SEED [PAIRS]]` prints it for other \
         seeds.\n"
    )?;
    paired_rows(doc, &bins)?;
    Ok(())
}
