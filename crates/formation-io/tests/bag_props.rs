//! Invariants of the bag reader and the MCAP writer: what the writer writes the reader reads
//! back exactly; no truncation or corruption of a bag, and no CDR payload, makes the reader
//! panic or ask for more memory than the file holds.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use formation_io::bag::Bag;
use formation_io::bag::cdr::{CameraInfo, CompressedImage, Image, TwistSample, mono8_image};
use formation_io::bag::mcap::McapReader;
use formation_io::mcap_out::McapWriter;
use proptest::prelude::*;

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("bag-props-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A small valid bag: CameraInfo-less, 4 frames of 8x6 mono8 on `/cam/image`.
fn small_bag() -> Vec<u8> {
    let mut w = McapWriter::new(Vec::new(), "ros2").unwrap();
    let s = w
        .add_schema("sensor_msgs/msg/Image", "ros2msg", b"")
        .unwrap();
    let c = w.add_channel(s, "/cam/image", "cdr").unwrap();
    for i in 0..4u64 {
        let t = 1_000_000_000 + i * 33_000_000;
        w.write(c, t, &mono8_image(t, "cam", 8, 6, &[i as u8 * 40; 48]))
            .unwrap();
    }
    w.finish().unwrap()
}

/// Reads every frame of `path` as `track` would, counting frames and errors.
fn read_all(path: &std::path::Path) -> (usize, usize) {
    let Ok(bag) = Bag::open(path) else {
        return (0, 1);
    };
    let mut frames = bag.frames("/cam/image", None, 64);
    let (mut ok, mut errors) = (0, 0);
    for _ in 0..100 {
        match frames.next_frame() {
            Ok(Some(f)) => {
                assert_eq!(f.image.data.len(), f.image.width * f.image.height);
                ok += 1;
            }
            Ok(None) => break,
            Err(e) => {
                errors += 1;
                assert!(!e.to_string().is_empty());
            }
        }
    }
    (ok, errors)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn what_the_writer_writes_the_reader_reads(
        messages in prop::collection::vec(
            (0u16..3, 0u64..1 << 40, prop::collection::vec(any::<u8>(), 0..200)),
            0..40,
        )
    ) {
        let mut w = McapWriter::new(Vec::new(), "").unwrap();
        let s = w.add_schema("x", "jsonschema", b"{}").unwrap();
        for topic in ["/a", "/b", "/c"] {
            w.add_channel(s, topic, "json").unwrap();
        }
        for (c, t, data) in &messages {
            w.write(*c, *t, data).unwrap();
        }
        let bytes = w.finish().unwrap();
        let path = tmp(&format!("roundtrip-{}.mcap", messages.len()));
        std::fs::write(&path, &bytes).unwrap();
        let mut r = McapReader::open(&path).unwrap();
        let summary = r.summary().unwrap().unwrap();
        prop_assert_eq!(summary.channels.len(), 3);
        prop_assert_eq!(
            summary.message_counts.values().sum::<u64>(),
            messages.len() as u64
        );
        let mut read = Vec::new();
        while let Some(m) = r.next_message().unwrap() {
            read.push((m.channel_id, m.log_time, m.data.to_vec()));
        }
        prop_assert_eq!(read, messages);
    }

    #[test]
    fn a_truncated_bag_never_panics_and_keeps_whole_frames(cut in 8usize..4000) {
        let bytes = small_bag();
        let cut = cut.min(bytes.len());
        let path = tmp(&format!("cut-{cut}.mcap"));
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let (ok, _) = read_all(&path);
        prop_assert!(ok <= 4);
    }

    #[test]
    fn a_corrupted_bag_never_panics(
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)
    ) {
        let mut bytes = small_bag();
        for (at, x) in &flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x | 1;
        }
        let path = tmp(&format!("flip-{}-{}.mcap", flips.len(), flips[0].1));
        std::fs::write(&path, &bytes).unwrap();
        let (ok, _) = read_all(&path);
        prop_assert!(ok <= 4);
    }

    #[test]
    fn cdr_parsers_never_panic_on_arbitrary_payloads(
        head in prop::sample::select(vec![[0u8, 1, 0, 0], [0, 0, 0, 0], [1, 2, 3, 4]]),
        body in prop::collection::vec(any::<u8>(), 0..600)
    ) {
        let mut p = head.to_vec();
        p.extend_from_slice(&body);
        let _ = Image::parse(&p);
        let _ = CompressedImage::parse(&p);
        let _ = CameraInfo::parse(&p);
        for t in ["nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"] {
            if let Ok(s) = TwistSample::parse(t, &p) {
                prop_assert!(s.v.is_finite() && s.w.is_finite());
            }
        }
        // A length prefix bigger than the payload is an error, not an allocation.
        if let Ok(img) = Image::parse(&p) {
            prop_assert!(img.data.len() <= p.len());
        }
    }
}

#[test]
fn the_small_bag_itself_reads_whole() {
    let path = tmp("whole.mcap");
    std::fs::write(&path, small_bag()).unwrap();
    assert_eq!(read_all(&path), (4, 0));
}
