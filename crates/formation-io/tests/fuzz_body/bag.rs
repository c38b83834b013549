//! ROS 2 bags (`formation_io::bag`: the MCAP reader, CDR messages, image
//! conversion): the bytes are written to a file and opened as a bag the way `track` opens
//! one; nothing panics, and every frame read has one grey byte per pixel within the size
//! limit, with inputs that are finite. At most 8 frames are read, at most 1024 px a side.

use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};

use formation_io::bag::Bag;

/// The pixel limit a side for fuzzing (the fixture bags' 640 x 480 frames pass; larger
/// frames are refused before decoding, which keeps each run short).
const MAX_SIDE: usize = 1024;

/// A file of its own for each run: runs may share a process, and tests run them on several
/// threads at once (each run removes its file when done, so the names are not reused).
fn scratch(data: &[u8]) -> Option<std::path::PathBuf> {
    static RUN: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "formation-bag-fuzz-{}-{}.mcap",
        std::process::id(),
        RUN.fetch_add(1, Ordering::Relaxed)
    ));
    let mut f = std::fs::File::create(&path).ok()?;
    f.write_all(data).ok()?;
    Some(path)
}

/// Opens `data` as an MCAP bag and reads its calibration and frames; returns how many
/// frames were read.
pub fn run(data: &[u8]) -> usize {
    let mut read = 0;
    let Some(path) = scratch(data) else {
        return read;
    };
    if let Ok(bag) = Bag::open(&path)
        && let Ok(topic) = bag.image_topic(None)
    {
        if let Ok(info) = bag.camera_info_topic(&topic)
            && let Ok(cal) = bag.calibration(&info)
        {
            assert!(cal.width > 0 && cal.height > 0);
        }
        let inputs = bag.inputs_topic(None).ok().flatten();
        let mut frames = bag.frames(&topic, inputs.as_deref(), MAX_SIDE);
        for _ in 0..8 {
            match frames.next_frame() {
                Ok(Some(f)) => {
                    read += 1;
                    let img = f.image;
                    assert!(img.width >= 1 && img.width <= MAX_SIDE);
                    assert!(img.height >= 1 && img.height <= MAX_SIDE);
                    assert_eq!(img.data.len(), img.width * img.height);
                    if let Some(u) = f.inputs {
                        assert!(u.v.is_finite() && u.w.is_finite(), "{u:?}");
                    }
                }
                Ok(None) => break,
                Err(e) if e.is_fatal() => break,
                Err(_) => {}
            }
        }
    }
    let _ = std::fs::remove_file(&path);
    read
}
