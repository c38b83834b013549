//! `cargo xtask photos`: our detector on real photographs, one photo at a time.
//!
//! Real frames are what a robot's camera sees: texture, edges, chessboards, JPEG artefacts.
//! This times [`Detector::detect`] (one thread, `--reps` runs after one warm-up, median, or
//! with `--least` the least) on every photo of `shared/realdata/photos/notags`, the NASA
//! robots, OpenCV's ArUco photo and the Duckietown frames, or on the photos and folders
//! named, and prints per photo its size, that time, the markers read and the detector's
//! work counters
//! ([`fiducial::DetectStats`]): where the time of a frame goes. The sums at the end are
//! what `cargo xtask compare`'s real-photo section compares with the peers.

use std::path::{Path, PathBuf};
use std::time::Instant;

use fiducial::{Detector, DetectorConfig, GrayView, dictionary_by_name};
use marker_testkit::reference::{RefTag, corner_error};

const USAGE: &str =
    "usage: cargo xtask photos [--reps N] [--dictionary NAME] [--clutter] [--scene] [--list] [--least] [--photometric] [--clusters] [PHOTO|FOLDER]...

--list: also print every marker read (id, corners rounded to pixels, bits corrected)
--least: time each photo by the least of its runs instead of the median (on a loaded
machine, the run the other processes disturbed least)
--clusters: detect with boundary clustering (DetectorConfig::boundary_clusters), as the CLI's
`detect` does by default; the library default leaves it off
--photometric: detect with the photometric step on markers whose cells are under
fiducial::PHOTOMETRIC_BELOW_PX (DetectorConfig::for_pose, the tracker's settings; the
library default leaves it off), to see what it costs on these photos
--clutter: first time the frame of the criterion bench fiducial/detect_clutter_640x480
(marker_testkit's clutter, seed 43), to see where its time goes
--scene: first time the frame of the criterion bench fiducial/detect_640x480 (marker_testkit's
accuracy scene, seed 42: 8 markers of the paper dictionary, 20-120 px), with the paper
dictionary whatever --dictionary says: the frame the clutter bench is compared with";

/// The frame of the bench `fiducial/detect_clutter_640x480`: `marker_testkit`'s clutter,
/// seed 43, without entries of the paper dictionary.
fn bench_clutter() -> crate::Result<Vec<u8>> {
    use rand::SeedableRng;
    fn paper_entry(code: u64) -> bool {
        fiducial::Dictionary::paper()
            .lookup_within(code, 0)
            .is_some()
    }
    let f = fiducial::Dictionary::paper().family();
    let not = marker_testkit::NotMarkers {
        rows: f.rows() as usize,
        cols: f.cols() as usize,
        is_marker: &paper_entry,
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(43);
    Ok(marker_testkit::clutter_frame(
        640, 480, 1.0, 3.0, not, &mut rng,
    )?)
}

/// The frame of the bench `fiducial/detect_640x480`: `marker_testkit`'s accuracy scene
/// (the default [`marker_testkit::SceneConfig`]), seed 42, markers of the paper dictionary.
fn bench_scene() -> crate::Result<Vec<u8>> {
    use rand::SeedableRng;
    let entries = crate::detector_accuracy::entries(fiducial::Dictionary::paper());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let cfg = marker_testkit::SceneConfig::default();
    Ok(marker_testkit::marker_scene(&cfg, &entries, &mut rng)?.pixels)
}

/// Photo files (PNG or JPEG) of `dir`, sorted by name.
pub(crate) fn photos_in(dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    v.sort();
    Ok(v)
}

/// The photos of `cargo xtask compare`'s real-photo section: every photo of
/// `shared/realdata/photos/notags` and the NASA photo.
pub(crate) fn compared_photos(root: &Path) -> crate::Result<Vec<PathBuf>> {
    let mut v = photos_in(&crate::realdata(root, "photos/notags")?)?;
    v.extend(photos_in(&crate::realdata(root, "nasa")?)?);
    Ok(v)
}

/// The default photo set: every real photo beside the repository (those compared, then
/// OpenCV's ArUco photo and the Duckietown frames).
fn default_photos(root: &Path) -> crate::Result<Vec<PathBuf>> {
    let mut v = compared_photos(root)?;
    for sub in ["photos/aruco", "duckietown"] {
        v.extend(photos_in(&crate::realdata(root, sub)?)?);
    }
    Ok(v)
}

/// A photo as grey pixels.
pub(crate) fn load_gray(path: &Path) -> crate::Result<(Vec<u8>, usize, usize)> {
    let img = image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .to_luma8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Ok((img.into_raw(), w, h))
}

/// The reference corners of a photo (`<photo>.txt` beside it, AprilTag's reading; see
/// `marker_testkit::reference`), in our pixel convention.
pub(crate) fn reference(photo: &Path) -> crate::Result<Option<Vec<RefTag>>> {
    let txt = photo.with_extension("txt");
    if !txt.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&txt)?;
    let tags =
        marker_testkit::reference::parse(&text).map_err(|e| format!("{}: {e}", txt.display()))?;
    Ok(Some(tags))
}

pub fn run(args: &[String]) -> crate::Result {
    let mut reps = 20usize;
    let mut dictionary = "tag36h11".to_string();
    let mut paths = Vec::new();
    let mut clutter = false;
    let mut scene = false;
    let mut list = false;
    let mut least = false;
    let mut config = DetectorConfig::default();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--reps" => {
                reps = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|&n| n > 0)
                    .ok_or("--reps needs a positive count")?
            }
            "--dictionary" => dictionary = it.next().ok_or("--dictionary needs a name")?.clone(),
            "--clutter" => clutter = true,
            "--scene" => scene = true,
            "--list" => list = true,
            "--least" => least = true,
            "--photometric" => config.refine.photometric_below_px = fiducial::PHOTOMETRIC_BELOW_PX,
            "--clusters" => config.boundary_clusters = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            s if s.starts_with('-') => return Err(format!("unknown option {s}\n{USAGE}").into()),
            s => {
                let p = PathBuf::from(s);
                if p.is_dir() {
                    paths.extend(photos_in(&p)?);
                } else {
                    paths.push(p);
                }
            }
        }
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .ok_or("xtask has no parent folder")?
        .to_path_buf();
    if paths.is_empty() && !clutter && !scene {
        paths = default_photos(&root)?;
    }
    let dict = dictionary_by_name(&dictionary)?.clone();
    let mut det = Detector::with_dictionary(config, dict);
    println!(
        "{:<34} {:>10} {:>9} {:>5}  work",
        "photo", "size", "ms", "reads"
    );
    let mut total = 0.0;
    if scene {
        let px = bench_scene()?;
        let mut paper = Detector::new(config);
        total += report(
            &mut paper,
            "accuracy_640x480 (bench, seed 42)",
            &GrayView::new(&px, 640, 480)?,
            Timing { reps, least },
            list,
            None,
        );
    }
    if clutter {
        let px = bench_clutter()?;
        let img = GrayView::new(&px, 640, 480)?;
        total += report(
            &mut det,
            "clutter_640x480 (bench, seed 43)",
            &img,
            Timing { reps, least },
            list,
            None,
        );
    }
    for p in &paths {
        let (px, w, h) = load_gray(p)?;
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let refs = reference(p)?;
        total += report(
            &mut det,
            &name,
            &GrayView::new(&px, w, h)?,
            Timing { reps, least },
            list,
            refs.as_deref(),
        );
    }
    let what = if least { "least times" } else { "medians" };
    println!("sum of {what}: {:.2} ms", 1e3 * total);
    Ok(())
}

/// How [`report`] times a photo: `reps` runs after one warm-up, summed up by their median
/// or, with `least`, their least.
#[derive(Clone, Copy)]
struct Timing {
    reps: usize,
    least: bool,
}

/// Times `det` on `img` (`timing`) and prints the median (or least) time, the reads,
/// the work counters and, with `list`, every marker read; for each tag of `refs`, whether
/// it was read (corners within 1 px), the nearest quad and why that quad was dropped.
/// Returns that time, seconds.
fn report(
    det: &mut Detector,
    name: &str,
    img: &GrayView<'_>,
    Timing { reps, least }: Timing,
    list: bool,
    refs: Option<&[RefTag]>,
) -> f64 {
    let mut out = Vec::new();
    det.detect(img, &mut out);
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        det.detect(img, &mut out);
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let med = if least {
        times[0]
    } else {
        times[times.len() / 2]
    };
    println!(
        "{:<34} {:>10} {:>9.3} {:>5}  {}",
        name,
        format!("{}x{}", img.width(), img.height()),
        1e3 * med,
        out.len(),
        det.stats()
    );
    if list {
        for d in &out {
            println!(
                "  read id {} corners {:?} distance {}",
                d.index,
                d.corners.map(|c| [c.x.round(), c.y.round()]),
                d.distance
            );
        }
    }
    for (id, want) in refs.unwrap_or_default() {
        let read = out
            .iter()
            .filter(|d| d.index == *id)
            .map(|d| corner_error(&d.corners, want))
            .fold(f64::INFINITY, f64::min);
        let nearest = det
            .quads()
            .iter()
            .map(|q| (corner_error(&q.corners, want), q.corners))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let quad = nearest.map_or(f64::INFINITY, |n| n.0);
        let why = match nearest {
            Some((e, c)) if read >= 3.0 && e < 3.0 => {
                match fiducial::decode(img, &c, det.dictionary(), &det.config().decode) {
                    Err(e) => format!(" decode: {e}"),
                    Ok(d) => match &det.config().side_check {
                        Some(check) => format!(
                            " decodes alone; side check: {:?}",
                            fiducial::stages_for_tools::side_offsets(
                                img,
                                &d,
                                det.dictionary().family(),
                                check
                            )
                        ),
                        None => " decodes alone".into(),
                    },
                }
            }
            _ => String::new(),
        };
        println!(
            "  reference tag {id} at ({:.0}, {:.0}): read {} (corner error {:.2} px), nearest quad {:.2} px{why}",
            want[0][0],
            want[0][1],
            read < 1.0,
            read,
            quad
        );
    }
    med
}
