//! `cargo xtask motion-sets [--scenes N] [--quick]`: issue #31's motion-blur item, "at 9 px at
//! least 1.2x the best peer's recall on scene sets you did not tune on". Nine sets of
//! 640x480 scenes, each on seeds no other command renders (so never used for tuning), vary
//! the marker size, the blur length and the blur direction one at a time; ours and the peers
//! read the same frames, and `docs/motion-blur-sets.md` reports each set.
//!
//! Everything but the sets is `compare`'s: its scene renderer (`compare::render_job`: the
//! same warps, markers, blur 1, noise 3 and box motion blur as its *motion 5* and *motion 9*
//! conditions), our detector in release as compare runs it (`compare::run_ours`), the peers
//! through the same script (`xtask/py/compare.py`, OpenCV ArUco and AprilTag 3 in
//! `target/py-venv`) and the same scoring (`compare::Tally`: the right id with its corners
//! within a quarter side of the truth; any other read is a false read). The pairings are
//! compare's: ours on tag36h11 against AprilTag 3 (decimate 1 and 2), ours on `DICT_4X4_100`
//! against OpenCV ArUco (no refinement, SUBPIX, ArUco3 mode).

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use serde_json::{Value, json};

use crate::compare::{
    BASE, Condition, DETECTORS, Family, Frame, Reads, Tally, peer_reads, run_ours,
};

const USAGE: &str = "usage: cargo xtask motion-sets [--scenes N] [--quick]

  --scenes N  scenes per set (default 40; 8 markers a scene, fewer in the 45-70 px set)
  --quick     5 scenes per set (for iterating; the document says so)";

/// Default scenes per set: 8 markers a scene, so about 320 markers a set and a standard
/// error of recall of at most 2.8 points.
const SCENES: usize = 40;

/// Scenes per set with `--quick`.
const QUICK_SCENES: usize = 5;

/// Set `i`'s scene `k` is compare's scene seed `SEED_BASE + SEED_STRIDE * i + k`. `compare`
/// seeds its 640x480 scenes `100 * condition + k` (below 800 plus three times its
/// `--scenes`) and its larger frames from 12,800,000 up, so these seeds are rendered by no
/// other command and were never used for tuning the detector.
const SEED_BASE: u64 = 31_000;
const SEED_STRIDE: u64 = 1_000;

/// The target of the item: ours at least this times the best peer's recall at 9 px.
const TARGET: f64 = 1.2;

/// One scene set: marker sides, blur length and direction (`None`: random per scene).
#[derive(Clone, Copy, Debug)]
struct Set {
    name: &'static str,
    /// What the set varies: "size", "length" or "direction".
    varies: &'static str,
    min_side: f64,
    max_side: f64,
    motion: f64,
    /// Degrees from the image's x axis (y down), or `None` for a random direction per scene.
    angle: Option<f64>,
}

impl Set {
    const fn new(
        name: &'static str,
        varies: &'static str,
        sides: (f64, f64),
        motion: f64,
        angle: Option<f64>,
    ) -> Set {
        Set {
            name,
            varies,
            min_side: sides.0,
            max_side: sides.1,
            motion,
            angle,
        }
    }

    fn condition(&self) -> Condition {
        Condition {
            name: self.name,
            min_side: self.min_side,
            max_side: self.max_side,
            motion: self.motion,
            motion_angle: self.angle.map(f64::to_radians),
            ..BASE
        }
    }

    fn direction(&self) -> String {
        self.angle
            .map_or_else(|| "random".to_string(), |a| format!("{a:.0} deg"))
    }
}

/// The sets, in the order of their seeds.
const SETS: [Set; 9] = [
    Set::new("size 14-28", "size", (14.0, 28.0), 9.0, None),
    Set::new("size 28-45", "size", (28.0, 45.0), 9.0, None),
    Set::new("size 45-70", "size", (45.0, 70.0), 9.0, None),
    Set::new("length 7", "length", (14.0, 70.0), 7.0, None),
    Set::new("length 9", "length", (14.0, 70.0), 9.0, None),
    Set::new("length 11", "length", (14.0, 70.0), 11.0, None),
    Set::new("horizontal", "direction", (14.0, 70.0), 9.0, Some(0.0)),
    Set::new("vertical", "direction", (14.0, 70.0), 9.0, Some(90.0)),
    Set::new("diagonal", "direction", (14.0, 70.0), 9.0, Some(45.0)),
];

/// The families drawn (those with a peer in compare).
const FAMILIES: [Family; 2] = [Family::Tag36h11, Family::Aruco4x4];

fn seed(set: usize, k: usize) -> u64 {
    SEED_BASE + SEED_STRIDE * set as u64 + k as u64
}

pub fn run(args: &[String]) -> crate::Result {
    let mut quick = false;
    let mut scenes = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--scenes" => scenes = Some(it.next().ok_or(USAGE)?.parse::<usize>()?),
            _ => return Err(USAGE.into()),
        }
    }
    if cfg!(debug_assertions) && std::env::var_os("XTASK_MOTION_SETS_RELEASE").is_none() {
        return crate::release::rerun_in_release("motion-sets", args, "XTASK_MOTION_SETS_RELEASE");
    }
    let scenes = scenes
        .unwrap_or(if quick { QUICK_SCENES } else { SCENES })
        .clamp(1, SEED_STRIDE as usize);
    let started = Instant::now();
    let load_before = crate::compare::loadavg();
    let (root, work, python) = crate::compare::fresh_work("motion-sets")?;

    eprintln!(
        "motion-sets: rendering {} sets x {scenes} scenes x {} families",
        SETS.len(),
        FAMILIES.len()
    );
    let frames = render(scenes, &work)?;
    eprintln!("motion-sets: our detector on {} frames", frames.len());
    let ours = run_ours(&frames, 1)?;
    let peers = run_peers(&python, &root, &work, &frames)?;
    let tallies = score(&frames, &ours, &peers)?;
    let machine = crate::compare::machine(&peers)?;
    let elapsed = started.elapsed().as_secs_f64();
    let doc = document(&Run {
        quick,
        scenes,
        tallies: &tallies,
        machine: &machine,
        elapsed,
        load: (load_before, crate::compare::loadavg()),
    })?;
    let path = root.join("docs/motion-blur-sets.md");
    crate::write_atomically(&path, &doc)?;
    std::fs::remove_dir_all(work.join("frames"))?;
    println!("motion-sets: wrote {} in {elapsed:.0} s", path.display());
    for line in summary(&tallies) {
        println!("  {line}");
    }
    Ok(())
}

/// Every set's scenes, each drawn once per family, in set order.
fn render(scenes: usize, work: &Path) -> crate::Result<Vec<Frame>> {
    let jobs: Vec<(usize, usize, Condition, u64)> = SETS
        .iter()
        .enumerate()
        .flat_map(|(i, set)| (0..scenes).map(move |k| (640, 480, set.condition(), seed(i, k))))
        .collect();
    crate::compare::render_jobs(&jobs, &FAMILIES, work)
}

/// The peers on every frame through compare's script (one untimed-for-the-report read per
/// frame; nothing else in its manifest).
fn run_peers(python: &Path, root: &Path, work: &Path, frames: &[Frame]) -> crate::Result<Value> {
    let manifest = json!({
        "reps": 1,
        "frames": frames.iter().map(Frame::to_json).collect::<Vec<_>>(),
        "real": [],
        "photos": [],
        "pose": {"k": crate::compare::POSE_K, "side": crate::compare::POSE_SIDE, "reps": 1,
                 "cases": []},
        "filter": [],
    });
    crate::compare::run_peers(python, root, work, &manifest, "motion-sets")
}

/// `tallies[set][detector]`: each of compare's detectors (`DETECTORS`) on its family's frames
/// of the set (the own family is not drawn: its tallies stay empty).
fn score(frames: &[Frame], ours: &[Reads], peers: &Value) -> crate::Result<Vec<Vec<Tally>>> {
    let mut out = vec![vec![Tally::default(); DETECTORS.len()]; SETS.len()];
    for (i, frame) in frames.iter().enumerate() {
        let s = SETS
            .iter()
            .position(|set| set.name == frame.condition)
            .ok_or("a frame of no set")?;
        for (d, det) in DETECTORS.iter().enumerate() {
            if det.family != frame.family {
                continue;
            }
            let reads = match det.peer {
                None => ours[i].markers.clone(),
                Some(key) => peer_reads(&peers["detection"][key][i])?.markers,
            };
            out[s][d].add(&frame.truth, &reads, det.conv);
        }
    }
    Ok(out)
}

/// Standard error of a recall in percentage points (binomial, markers independent).
fn se(t: &Tally) -> f64 {
    let n = t.total.max(1) as f64;
    let p = t.found as f64 / n;
    100.0 * (p * (1.0 - p) / n).sqrt()
}

/// `ours / best` and its standard error by the delta method, the two recalls taken as
/// independent (they are read on the same markers, so this overstates the spread).
fn ratio(ours: &Tally, best: &Tally) -> (f64, f64) {
    let (o, b) = (ours.recall(), best.recall());
    let r = o / b;
    let rel = |t: &Tally, v: f64| if v > 0.0 { se(t) / v } else { f64::NAN };
    (r, r * rel(ours, o).hypot(rel(best, b)))
}

/// One pairing: ours on `family` and the peers that read it.
struct Pairing {
    family: Family,
    ours: usize,
    peers: Vec<usize>,
}

fn pairings() -> Vec<Pairing> {
    FAMILIES
        .iter()
        .map(|&family| Pairing {
            family,
            ours: DETECTORS
                .iter()
                .position(|d| d.peer.is_none() && d.family == family)
                .unwrap_or(0),
            peers: DETECTORS
                .iter()
                .enumerate()
                .filter(|(_, d)| d.peer.is_some() && d.family == family)
                .map(|(i, _)| i)
                .collect(),
        })
        .collect()
}

/// The peer with the highest recall among `p.peers` in `t` (the first on a tie).
fn best_peer(p: &Pairing, t: &[Tally]) -> usize {
    p.peers
        .iter()
        .copied()
        .reduce(|a, b| if t[b].found > t[a].found { b } else { a })
        .unwrap_or(0)
}

/// Sum of the tallies of the sets with `motion` px of blur, per detector.
fn pooled(tallies: &[Vec<Tally>], motion: f64) -> Vec<Tally> {
    let mut out = vec![Tally::default(); DETECTORS.len()];
    for (set, t) in SETS.iter().zip(tallies) {
        if set.motion != motion {
            continue;
        }
        for (o, x) in out.iter_mut().zip(t) {
            o.total += x.total;
            o.found += x.found;
            o.wrong += x.wrong;
        }
    }
    out
}

/// Fewer reads than this by the best peer and the ratio's standard error means nothing (its
/// denominator is a handful of markers): the verdict then asks for a clear separation.
const FEW: usize = 10;

/// Whether ours reaches [`TARGET`] times the best peer's recall, and the verdict's wording.
/// When the best peer reads fewer than [`FEW`] markers, met only if ours's recall less two
/// standard errors exceeds the target times the peer's plus two (otherwise undecided,
/// counted as not met).
fn verdict(set_motion: f64, ours: &Tally, best: &Tally) -> (bool, String) {
    let (r, r_se) = ratio(ours, best);
    let (met, note) = if best.found < FEW {
        let clear = ours.recall() - 2.0 * se(ours) > TARGET * (best.recall() + 2.0 * se(best));
        let note = format!(
            "the best peer reads {} of {}, ours {}",
            best.found, best.total, ours.found
        );
        if clear {
            (true, format!("clear of {TARGET}x by two SE; {note}"))
        } else {
            (false, format!("undecided: {note}"))
        }
    } else if r < TARGET && best.recall() * TARGET > 100.0 {
        (
            false,
            format!(
                "out of reach: the best peer reads over {:.1} %",
                100.0 / TARGET
            ),
        )
    } else {
        let within = ((r - TARGET) / r_se).abs() < 1.0;
        (
            r >= TARGET,
            if within {
                "within one SE".into()
            } else {
                String::new()
            },
        )
    };
    let word = if met { "met" } else { "not met" };
    let note = if note.is_empty() {
        String::new()
    } else {
        format!(" ({note})")
    };
    let text = if set_motion == 9.0 {
        format!("**{word}**{note}")
    } else {
        format!("no target at {set_motion:.0} px; against {TARGET}x: {word}{note}")
    };
    (met, text)
}

/// `ours / best ± se`, or why there is no ratio.
fn ratio_cell(ours: &Tally, best: &Tally) -> String {
    if best.found == 0 {
        return "- (best peer 0 %)".into();
    }
    let (r, r_se) = ratio(ours, best);
    if best.found < FEW {
        return format!("{r:.1} (best peer {} reads)", best.found);
    }
    format!("{r:.2} ± {r_se:.2}")
}

/// One line per set and pairing, for the terminal.
fn summary(tallies: &[Vec<Tally>]) -> Vec<String> {
    let mut out = Vec::new();
    for p in pairings() {
        for (set, t) in SETS.iter().zip(tallies) {
            let b = best_peer(&p, t);
            out.push(format!(
                "{} {:<11} ours {:5.1} %  {} {:5.1} %  ratio {}",
                p.family.key(),
                set.name,
                t[p.ours].recall(),
                DETECTORS[b].label,
                t[b].recall(),
                ratio_cell(&t[p.ours], &t[b])
            ));
        }
    }
    out
}

struct Run<'a> {
    quick: bool,
    scenes: usize,
    tallies: &'a [Vec<Tally>],
    machine: &'a crate::compare::Machine,
    elapsed: f64,
    load: (Option<f64>, Option<f64>),
}

fn document(run: &Run<'_>) -> crate::Result<String> {
    let mut doc = String::new();
    let last_seed = seed(SETS.len() - 1, run.scenes - 1);
    writeln!(doc, "# Motion blur on held-out scene sets\n")?;
    writeln!(
        doc,
        "Generated by `cargo xtask motion-sets{}` ({} scenes per set, {:.0} s on this machine; \
         do not edit by hand). Issue #31's item: *motion blur at 9 px at least {TARGET}x the \
         best peer's recall on scene sets you did not tune on: vary marker sizes (14-70 px), \
         blur lengths (7-11 px) and directions, and report each set.*{}\n",
        if run.quick {
            " --quick".to_string()
        } else if run.scenes != SCENES {
            format!(" --scenes {}", run.scenes)
        } else {
            String::new()
        },
        run.scenes,
        run.elapsed,
        if run.quick {
            " **--quick: few scenes, for iterating, not for quoting.**"
        } else {
            ""
        }
    )?;
    writeln!(
        doc,
        "**Seeds.** Set *i* (0-8, in the order of the tables) renders scenes \
         `{SEED_BASE} + {SEED_STRIDE} i + k`, k = 0..{}, through `compare`'s scene renderer \
         (its generator is seeded with 1,000,000 plus the scene seed), so seeds {SEED_BASE} to \
         {last_seed}. `cargo xtask compare` seeds its 640x480 scenes `100 c + k` (below 800 \
         plus three times its `--scenes`; its *motion 9* rows, on which the detector's \
         motion-blur handling was tuned, are seeds 700-735) and its larger frames from \
         12,800,000 up; no other command renders these seeds. **These seeds were never used \
         for tuning**: the sets were first rendered when this document was generated, and no \
         detector change was made from them.\n",
        run.scenes - 1
    )?;
    writeln!(
        doc,
        "**Settings.** 640x480 frames, 8 markers a scene where they fit without overlap (the \
         45-70 px set places fewer: the count is in the tables), each family's markers drawn \
         into the same warps (random distinct ids, rotation, perspective jitter of up to 12 % \
         of the side per corner), white background, uniform light, Gaussian blur sigma 1 px \
         and noise sigma 3 grey levels, then a centred box motion blur (`marker_testkit::\
         motion_blur`, so the true corners do not move): exactly compare's *motion 5* and \
         *motion 9* conditions except for the marker sides (the longer side drawn uniformly \
         in the set's range; compare's are 20-70 px), the blur length and, in the direction \
         sets, a fixed direction (measured from the image's x axis, y down; *random*: \
         uniform in 0-180 deg per scene, the same for every family). Sets: by marker size \
         14-28, 28-45 and 45-70 px at 9 px, random direction; by blur length 7, 9 and 11 px, \
         markers of 14-70 px, random direction; by direction 0 deg (horizontal), 90 deg \
         (vertical) and 45 deg (diagonal) at 9 px, markers of 14-70 px.\n"
    )?;
    writeln!(
        doc,
        "**Detectors and scoring** are compare's (see [comparison.md](comparison.md)): ours \
         in-process, release build, default `DetectorConfig`, with the family's dictionary; \
         OpenCV ArUco (`DICT_4X4_100`: no refinement, SUBPIX, ArUco3 mode) and AprilTag 3 \
         (pupil-apriltags, tag36h11, decimate 1 and 2) through `xtask/py/compare.py` on the \
         same PNG files. A marker is *found* when a read has its id and its corners (after \
         each library's convention is brought to ours) lie within a quarter of the side of \
         the true corners; *false* counts every other read (an id not in the frame, or a \
         true id a quarter side or more away). Our own dictionary has no peer and is not \
         drawn here.\n"
    )?;
    writeln!(
        doc,
        "**How to read it.** *recall* is markers found over markers drawn (%), ± its \
         standard error (binomial, markers taken as independent; markers of one scene share \
         its blur direction and noise, so the true spread is somewhat larger). *ours / best* \
         is our recall over the recall of the best peer on that set (the peer column in \
         bold), ± a standard error by the delta method that treats the two recalls as \
         independent (they are read on the same markers, so this overstates the spread of \
         the ratio). The item's target is ours / best >= {TARGET} on the 9 px sets (all but \
         *length 7* and *length 11*, which are reported for the trend); *within one SE* marks \
         a verdict that one standard error of the ratio would turn over. Where the best peer \
         reads fewer than {FEW} markers the ratio and its error mean little: the set counts as \
         met only if ours's recall less two standard errors exceeds {TARGET} times the \
         peer's plus two, and is otherwise *undecided* (counted as not met). Where the best peer reads more than {:.1} % the target cannot \
         be reached (a recall cannot exceed 100 %); such a set counts as not met.\n",
        100.0 / TARGET
    )?;
    let pairs = pairings();
    for p in &pairs {
        let title = match p.family {
            Family::Tag36h11 => "tag36h11: ours against AprilTag 3",
            _ => "DICT_4X4_100: ours against OpenCV ArUco",
        };
        writeln!(doc, "## {title}\n")?;
        let mut header =
            "| set | sides (px) | blur (px) | direction | markers | ours recall (%) |".to_string();
        let mut sep = "| --- | --- | --- | --- | --- | --- |".to_string();
        for &d in &p.peers {
            write!(header, " {} (%) |", DETECTORS[d].label)?;
            sep.push_str(" --- |");
        }
        header.push_str(" false reads (ours; peers) | ours / best | verdict |");
        sep.push_str(" --- | --- | --- |");
        writeln!(doc, "{header}\n{sep}")?;
        let mut rows: Vec<(String, &Set, Vec<Tally>)> = SETS
            .iter()
            .zip(run.tallies)
            .map(|(s, t)| (s.name.to_string(), s, t.clone()))
            .collect();
        let pooled9 = pooled(run.tallies, 9.0);
        let all9 = Set::new("all 9 px sets", "pooled", (14.0, 70.0), 9.0, None);
        rows.push(("**all 9 px sets**".to_string(), &all9, pooled9));
        for (name, set, t) in &rows {
            let b = best_peer(p, t);
            let sides = if set.varies == "pooled" {
                "14-70".to_string()
            } else {
                format!("{:.0}-{:.0}", set.min_side, set.max_side)
            };
            let direction = if set.varies == "pooled" {
                "all".to_string()
            } else {
                set.direction()
            };
            write!(
                doc,
                "| {name} | {sides} | {:.0} | {direction} | {} | {:.1} ± {:.1} |",
                set.motion,
                t[p.ours].total,
                t[p.ours].recall(),
                se(&t[p.ours])
            )?;
            for &d in &p.peers {
                let cell = format!("{:.1} ± {:.1}", t[d].recall(), se(&t[d]));
                if d == b {
                    write!(doc, " **{cell}** |")?;
                } else {
                    write!(doc, " {cell} |")?;
                }
            }
            let peers_false: Vec<String> =
                p.peers.iter().map(|&d| t[d].wrong.to_string()).collect();
            writeln!(
                doc,
                " {}; {} | {} | {} |",
                t[p.ours].wrong,
                peers_false.join(", "),
                ratio_cell(&t[p.ours], &t[b]),
                verdict(set.motion, &t[p.ours], &t[b]).1
            )?;
        }
        writeln!(
            doc,
            "\n*all 9 px sets* pools the seven 9 px sets (three sizes, the 9 px length set, three \
             directions; disjoint scenes). Markers drawn are the same for every detector of a \
             family (one set of warps per scene).\n"
        )?;
    }
    writeln!(doc, "## Verdict\n")?;
    for p in &pairs {
        let (mut met, mut total) = (0, 0);
        let mut misses = Vec::new();
        for (set, t) in SETS.iter().zip(run.tallies) {
            if set.motion != 9.0 {
                continue;
            }
            total += 1;
            let b = best_peer(p, t);
            if verdict(set.motion, &t[p.ours], &t[b]).0 {
                met += 1;
            } else {
                misses.push(format!(
                    "{}: ours {:.1} %, {} {:.1} %, {}",
                    set.name,
                    t[p.ours].recall(),
                    DETECTORS[b].label,
                    t[b].recall(),
                    ratio_cell(&t[p.ours], &t[b])
                ));
            }
        }
        let pooled9 = pooled(run.tallies, 9.0);
        let b = best_peer(p, &pooled9);
        let (r, r_se) = ratio(&pooled9[p.ours], &pooled9[b]);
        writeln!(
            doc,
            "- {}: ours / best peer >= {TARGET} on {met} of the {total} 9 px sets{}; pooled \
             {r:.2} ± {r_se:.2} (ours {:.1} %, {} {:.1} %).",
            p.family.key(),
            if misses.is_empty() {
                String::new()
            } else {
                format!(" (not on: {})", misses.join("; "))
            },
            pooled9[p.ours].recall(),
            DETECTORS[b].label,
            pooled9[b].recall()
        )?;
    }
    writeln!(doc)?;
    run.machine.write_table(&mut doc, "")?;
    writeln!(
        doc,
        "\nNothing here is timed (recall does not depend on load); the run took {:.0} s \
         (rendering, our detector, the peers), one-minute load average {} at the start and {} \
         at the end.",
        run.elapsed,
        run.load
            .0
            .map_or("unknown".to_string(), |l| format!("{l:.1}")),
        run.load
            .1
            .map_or("unknown".to_string(), |l| format!("{l:.1}")),
    )?;
    Ok(doc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sets_are_the_issues() {
        let nine = SETS.iter().filter(|s| s.motion == 9.0).count();
        assert_eq!(nine, 7);
        for s in &SETS {
            assert!(s.min_side >= 14.0 && s.max_side <= 70.0, "{s:?}");
            assert!((7.0..=11.0).contains(&s.motion), "{s:?}");
            let c = s.condition();
            assert_eq!(
                (c.blur, c.noise, c.lighting, c.clutter),
                (1.0, 3.0, 1.0, false)
            );
        }
        let lengths: Vec<f64> = SETS
            .iter()
            .filter(|s| s.varies == "length")
            .map(|s| s.motion)
            .collect();
        assert_eq!(lengths, [7.0, 9.0, 11.0]);
        let angles: Vec<Option<f64>> = SETS
            .iter()
            .filter(|s| s.varies == "direction")
            .map(|s| s.angle)
            .collect();
        assert_eq!(angles, [Some(0.0), Some(90.0), Some(45.0)]);
    }

    #[test]
    fn seeds_are_disjoint_from_compare_and_between_sets() {
        // compare: 100 * condition + k for its 8 conditions (k below 3 x --scenes; 36 by
        // default), and 10,000 x width + k for the larger frames.
        assert!(seed(0, 0) > 800 + 3 * 1_000);
        assert!(seed(SETS.len() - 1, SEED_STRIDE as usize - 1) < 10_000 * 1280);
        assert!(seed(1, 0) > seed(0, SEED_STRIDE as usize - 1));
    }

    #[test]
    fn ratio_and_standard_errors() {
        let t = |total, found| {
            let mut x = Tally::default();
            (x.total, x.found) = (total, found);
            x
        };
        let (ours, peer) = (t(400, 240), t(400, 200));
        assert!((se(&ours) - 100.0 * (0.6 * 0.4 / 400.0f64).sqrt()).abs() < 1e-12);
        let (r, r_se) = ratio(&ours, &peer);
        assert!((r - 1.2).abs() < 1e-12);
        assert!(r_se > 0.05 && r_se < 0.15, "{r_se}");
        let v = verdict(9.0, &ours, &peer);
        assert!(v.0 && v.1.contains("within one SE"), "{v:?}");
        assert_eq!(
            verdict(9.0, &t(4000, 3000), &t(4000, 2000)),
            (true, "**met**".to_string())
        );
        assert_eq!(
            verdict(9.0, &t(4000, 2000), &t(4000, 2000)).1,
            "**not met**"
        );
        assert!(verdict(7.0, &ours, &peer).1.contains("no target"));
        // Few peer reads: a clear separation or undecided; out of reach above 1 / 1.2.
        assert!(verdict(9.0, &t(320, 49), &t(320, 1)).0);
        assert!(!verdict(9.0, &t(320, 3), &t(320, 0)).0);
        assert!(verdict(9.0, &t(320, 3), &t(320, 0)).1.contains("undecided"));
        assert!(ratio_cell(&t(40, 3), &t(40, 0)).contains("0 %"));
        assert!(
            verdict(9.0, &t(40, 40), &t(40, 38))
                .1
                .contains("out of reach")
        );
    }

    /// Issue #31: the one false read of ours in the sets, `DICT_4X4_100` in *length 11*
    /// (seed 36021; 11 px of motion over a 30 px marker, 2.2 of its cells). The first cut
    /// finds no quad at marker 22; the second look's re-cut finds one over its SE half
    /// (one smeared light cell inside it, its NW side along the other), whose plain
    /// reading is entry 17 with no bit corrected. The side check has evidence on one side
    /// only (entry 17 has light data cells next to one side of the border), measures 4.2
    /// px of motion from the quad's own edges and so allows 2.9 px there; nothing it
    /// measures is out of tolerance. Ignored until that is fixed.
    #[test]
    #[ignore = "known false read, issue #31"]
    fn the_length_11_aruco_scene_21_reads_nothing_false() {
        use crate::compare::Family;
        let set = 5;
        assert_eq!(SETS[set].name, "length 11");
        let work = std::env::temp_dir().join(format!("motion-sets-{}", std::process::id()));
        std::fs::create_dir_all(work.join("frames")).unwrap();
        let job = (640, 480, SETS[set].condition(), seed(set, 21));
        let frames = crate::compare::render_jobs(&[job], &[Family::Aruco4x4], &work).unwrap();
        let ours = run_ours(&frames, 1).unwrap();
        std::fs::remove_dir_all(&work).unwrap();
        let det = DETECTORS
            .iter()
            .find(|d| d.peer.is_none() && d.family == Family::Aruco4x4)
            .unwrap();
        let mut t = Tally::default();
        t.add(&frames[0].truth, &ours[0].markers, det.conv);
        assert_eq!(t.wrong, 0, "reads {:?}", ours[0].markers);
    }

    #[test]
    fn pairings_are_compares() {
        let p = pairings();
        assert_eq!(p.len(), 2);
        for pair in &p {
            assert!(DETECTORS[pair.ours].peer.is_none());
            assert_eq!(DETECTORS[pair.ours].family, pair.family);
            assert!(!pair.peers.is_empty());
        }
        let t: Vec<Tally> = (0..DETECTORS.len())
            .map(|i| {
                let mut x = Tally::default();
                (x.total, x.found) = (10, i);
                x
            })
            .collect();
        assert_eq!(best_peer(&p[0], &t), *p[0].peers.iter().max().unwrap_or(&0));
    }
}
