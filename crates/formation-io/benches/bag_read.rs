//! What reading frames from a ROS 2 bag adds to the per-frame pipeline (issue #10: at most
//! 10 %), measured in one run so the ratio survives a loaded machine.
//!
//! The demo's frames (from the zstd fixture bag, `cargo xtask bags`) are rewritten into an
//! uncompressed bag in the target directory. Benchmarks, each over all 16 frames:
//! - `cli/pipeline_16_frames`: the pipeline (detect, pose, track) on frames already in memory
//!   (a fresh pipeline each time, built outside the timing);
//! - `cli/bag_read_16_frames`: opening the uncompressed bag (its summary) and reading every
//!   frame (MCAP records, chunk CRCs, CDR, `mono8` to the grey buffer, the reorder window,
//!   the odometry), without the pipeline.
//!
//! The ratio `bag_read / pipeline` is the share reading adds (`docs/performance.md`).

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use fiducial::{Detector, DetectorConfig, Dictionary};
use formation_io::bag::Bag;
use formation_io::bag::mcap::McapReader;
use formation_io::frames::GreyImage;
use formation_io::mcap_out::McapWriter;
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::Pipeline;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;
use formation_tracker::tracker::{Tracker, TrackerConfig};
use pose::PoseSolver;
use unicycle::Inputs;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bags/demo_zstd.mcap")
}

/// The fixture bag rewritten without compression.
fn uncompressed() -> PathBuf {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("bench-demo-uncompressed.mcap");
    let mut r = McapReader::open(&fixture()).expect("the fixture bag (cargo xtask bags)");
    let file = std::fs::File::create(&out).expect("writable target dir");
    let mut w = McapWriter::new(std::io::BufWriter::new(file), "ros2").expect("write");
    let mut ids = std::collections::BTreeMap::new();
    while let Some(m) = r.next_message().expect("a good fixture") {
        let (id, t) = (m.channel_id, m.log_time);
        let data = m.data.to_vec();
        let new = match ids.get(&id) {
            Some(n) => *n,
            None => {
                let c = r.channels()[&id].clone();
                let s = &r.schemas()[&c.schema_id];
                let sid = w.add_schema(&s.name, &s.encoding, b"").expect("write");
                let n = w
                    .add_channel(sid, &c.topic, &c.message_encoding)
                    .expect("write");
                ids.insert(id, n);
                n
            }
        };
        w.write(new, t, &data).expect("write");
    }
    w.finish().expect("write");
    out
}

fn read_all(bag: &Path) -> Vec<GreyImage> {
    let bag = Bag::open(bag).expect("bag");
    let mut frames = bag.frames("/camera/image_raw", Some("/odom"), 16_384);
    let mut out = Vec::new();
    while let Some(f) = frames.next_frame().expect("frame") {
        out.push(f.image.clone());
    }
    out
}

fn pipeline(bag: &Path) -> Pipeline {
    let b = Bag::open(bag).expect("bag");
    let c = b.calibration("/camera/camera_info").expect("calibration");
    let tracker = Tracker::new(TrackerConfig::reference(
        CameraMount::default().offset,
        1.0 / 30.0,
    ))
    .expect("tracker");
    Pipeline::new(
        Detector::with_dictionary(DetectorConfig::default(), Dictionary::paper().clone()),
        PoseSolver::new(c.intrinsics).with_distortion(c.distortion),
        (c.width, c.height),
        RigModel::reference(),
        RobotConfig::default(),
        tracker,
    )
}

fn benches(c: &mut Criterion) {
    let bag = uncompressed();
    let frames = read_all(&bag);
    assert_eq!(frames.len(), 16);
    // A fresh pipeline per iteration (the tracker's time must increase), built outside the
    // timing.
    c.bench_function("cli/pipeline_16_frames", |b| {
        b.iter_batched(
            || pipeline(&bag),
            |mut p| {
                let mut n = 0;
                for (i, f) in frames.iter().enumerate() {
                    let r = p
                        .process(
                            &f.data,
                            f.width,
                            f.height,
                            i as f64 / 30.0,
                            Inputs::new(0.0, 0.0),
                            CameraMount::default(),
                        )
                        .expect("frame");
                    n += r.markers;
                }
                black_box(n)
            },
            BatchSize::LargeInput,
        )
    });
    c.bench_function("cli/bag_read_16_frames", |b| {
        b.iter(|| {
            let bag = Bag::open(&bag).expect("bag");
            let mut frames = bag.frames("/camera/image_raw", Some("/odom"), 16_384);
            let mut sum = 0u64;
            while let Some(f) = frames.next_frame().expect("frame") {
                sum += u64::from(f.image.data[f.image.data.len() / 2]);
            }
            black_box(sum)
        })
    });
}

criterion_group! {
    name = group;
    config = Criterion::default().sample_size(20);
    targets = benches
}
criterion_main!(group);
