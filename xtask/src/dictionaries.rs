//! `cargo xtask dictionaries [--check]`: regenerates the standard marker families' bit
//! tables (`crates/fiducial/data/families/`) and the OpenCV-drawn cross-check markers
//! (`fixtures/markers/`) from OpenCV itself.
//!
//! It makes a Python virtual environment under `target/py-venv` (once), pip-installs a
//! pinned OpenCV, and runs `dictionaries.py`, which reads every predefined `cv2.aruco`
//! dictionary (checking OpenCV's bit matrix against the image OpenCV draws) and draws a few
//! markers per dictionary. This module then writes compact tables: one per distinct code
//! list (`DICT_4X4_50` to `DICT_4X4_1000` are prefixes of one list, which is checked), an
//! index with each OpenCV name's table, code count, `maxCorrectionBits` and minimum
//! distance over rotations (computed here), and the licence notices.
//!
//! With `--check`, everything is regenerated under `target/dictionaries/check/` and compared
//! byte for byte with the checked-in files instead of written.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use fiducial::{MarkerFamily, hamming};

const SCRIPT: &str = include_str!("dictionaries.py");

/// AprilTag's licence (the families `DICT_APRILTAG_*` are AprilTag's codes).
const APRILTAG_NOTICE: &str = "\
The DICT_APRILTAG_* tables (apriltag-*.txt) hold the codes of the AprilTag families
tag16h5, tag25h9, tag36h10 and tag36h11, as shipped in OpenCV's aruco module, which took
them from the AprilTag library. AprilTag's licence:

Copyright (C) 2013-2016, The Regents of The University of Michigan.
All rights reserved.

Redistribution and use in source and binary forms, with or without
modification, are permitted provided that the following conditions are met:

1. Redistributions of source code must retain the above copyright notice, this
   list of conditions and the following disclaimer.
2. Redistributions in binary form must reproduce the above copyright notice,
   this list of conditions and the following disclaimer in the documentation
   and/or other materials provided with the distribution.

THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS \"AS IS\" AND
ANY EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE IMPLIED
WARRANTIES OF MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE
DISCLAIMED. IN NO EVENT SHALL THE COPYRIGHT OWNER OR CONTRIBUTORS BE LIABLE FOR
ANY DIRECT, INDIRECT, INCIDENTAL, SPECIAL, EXEMPLARY, OR CONSEQUENTIAL DAMAGES
(INCLUDING, BUT NOT LIMITED TO, PROCUREMENT OF SUBSTITUTE GOODS OR SERVICES;
LOSS OF USE, DATA, OR PROFITS; OR BUSINESS INTERRUPTION) HOWEVER CAUSED AND
ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT LIABILITY, OR TORT
(INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE OF THIS
SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.

The views and conclusions contained in the software and documentation are those
of the authors and should not be interpreted as representing official policies,
either expressed or implied, of the Regents of The University of Michigan.
";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The OpenCV notice, followed by the Apache-2.0 text (the repository's own copy).
fn opencv_notice(version: &str) -> crate::Result<String> {
    let apache = std::fs::read_to_string(root().join("LICENSE-APACHE"))?;
    Ok(format!(
        "The tables in this folder (and the marker images in fixtures/markers/) were generated
from OpenCV {version} (cv2.aruco predefined dictionaries, opencv-contrib-python-headless)
by `cargo xtask dictionaries`. OpenCV is licensed under the Apache License, Version 2.0:

OpenCV: Copyright (C) 2000-2025, OpenCV Foundation and contributors (https://opencv.org).
The ArUco dictionaries (DICT_4X4_* to DICT_7X7_*, DICT_ARUCO_ORIGINAL,
DICT_ARUCO_MIP_36h12) come from the ArUco library by Rafael Munoz-Salinas et al., as
included in OpenCV under the same licence. The DICT_APRILTAG_* codes are AprilTag's; see
LICENSE-AprilTag.txt.

{apache}"
    ))
}

/// Table file name of an OpenCV dictionary: the `NxN_count` ones share one list per size.
fn table_name(name: &str) -> String {
    let lower = name.trim_start_matches("DICT_").to_ascii_lowercase();
    if let Some((size, _)) = lower.split_once('_')
        && size.len() == 3
        && size.as_bytes()[1] == b'x'
    {
        return format!("aruco-{size}");
    }
    lower.replace('_', "-")
}

struct Dict {
    name: String,
    opencv_enum: u64,
    size: u32,
    max_correction_bits: u64,
    codes: Vec<u64>,
}

fn parse(json: &serde_json::Value) -> crate::Result<(String, Vec<Dict>)> {
    let version = json["opencv_version"]
        .as_str()
        .ok_or("opencv.json: no opencv_version")?
        .to_string();
    let mut out = Vec::new();
    for d in json["dictionaries"]
        .as_array()
        .ok_or("opencv.json: no dictionaries")?
    {
        let field = |k: &str| d[k].as_u64().ok_or(format!("opencv.json: bad {k}"));
        out.push(Dict {
            name: d["name"]
                .as_str()
                .ok_or("opencv.json: bad name")?
                .to_string(),
            opencv_enum: field("opencv_enum")?,
            size: field("marker_size")? as u32,
            max_correction_bits: field("max_correction_bits")?,
            codes: d["codes"]
                .as_array()
                .ok_or("opencv.json: bad codes")?
                .iter()
                .map(|c| c.as_u64().ok_or("opencv.json: bad code"))
                .collect::<Result<_, _>>()?,
        });
    }
    Ok((version, out))
}

/// Smallest Hamming distance between any two codes under any rotation, and between each
/// code and its own rotations (0 if two entries coincide up to rotation).
fn min_distance(family: MarkerFamily, codes: &[u64]) -> crate::Result<u32> {
    let mut rotated = Vec::with_capacity(codes.len());
    for &c in codes {
        let mut r = [0u64; 4];
        for q in 0..4u8 {
            r[q as usize] = family.rotate(c, q)?;
        }
        rotated.push(r);
    }
    let mut best = u32::MAX;
    for (i, ri) in rotated.iter().enumerate() {
        for r in &ri[1..] {
            best = best.min(hamming(ri[0], *r));
        }
        for rj in &rotated[i + 1..] {
            for r in rj {
                best = best.min(hamming(ri[0], *r));
            }
        }
    }
    Ok(best)
}

/// Writes every generated file under `data_dir` (tables) and `fixture_dir` (PNGs are copied
/// from `png_dir`).
fn write_outputs(
    version: &str,
    dicts: &[Dict],
    png_dir: &Path,
    data_dir: &Path,
    fixture_dir: &Path,
) -> crate::Result {
    std::fs::create_dir_all(data_dir)?;
    std::fs::create_dir_all(fixture_dir)?;
    // Tables: the longest list of each table; the others must be its prefixes.
    let mut tables: BTreeMap<String, &Dict> = BTreeMap::new();
    for d in dicts {
        let t = table_name(&d.name);
        let entry = tables.entry(t).or_insert(d);
        if d.codes.len() > entry.codes.len() {
            *entry = d;
        }
    }
    for d in dicts {
        let t = &tables[&table_name(&d.name)];
        if t.size != d.size || t.codes[..d.codes.len()] != d.codes[..] {
            return Err(format!("{} is not a prefix of {}", d.name, t.name).into());
        }
    }
    for (t, d) in &tables {
        let mut s = format!(
            "# Codes of {} from OpenCV {version} (cv2.aruco), id order. Generated by\n\
             # `cargo xtask dictionaries`; do not edit. Licence: LICENSE-OpenCV.txt{}.\n\
             # Data bit k = row * {} + col (row 0 top, col 0 left, as OpenCV draws the marker),\n\
             # black = 1; hexadecimal, eight codes a line.\n",
            d.name,
            if t.starts_with("apriltag") {
                " and LICENSE-AprilTag.txt"
            } else {
                ""
            },
            d.size
        );
        s.push_str(&format!("size {}\ncount {}\n", d.size, d.codes.len()));
        for chunk in d.codes.chunks(8) {
            let line: Vec<String> = chunk.iter().map(|c| format!("{c:x}")).collect();
            s.push_str(&line.join(" "));
            s.push('\n');
        }
        std::fs::write(data_dir.join(format!("{t}.txt")), s)?;
    }
    // Index.
    let mut index = format!(
        "# OpenCV {version} predefined dictionaries. Generated by `cargo xtask dictionaries`;\n\
         # do not edit. Columns: OpenCV name, OpenCV enum value, table file (.txt), number\n\
         # of codes (a prefix of the table), OpenCV maxCorrectionBits, minimum Hamming\n\
         # distance between codes over rotations (computed; 0 = two ids coincide).\n"
    );
    for d in dicts {
        let family = MarkerFamily::new(d.size, d.size)?;
        let dmin = min_distance(family, &d.codes)?;
        index.push_str(&format!(
            "{} {} {} {} {} {}\n",
            d.name,
            d.opencv_enum,
            table_name(&d.name),
            d.codes.len(),
            d.max_correction_bits,
            dmin
        ));
    }
    std::fs::write(data_dir.join("index.txt"), index)?;
    std::fs::write(data_dir.join("LICENSE-OpenCV.txt"), opencv_notice(version)?)?;
    std::fs::write(data_dir.join("LICENSE-AprilTag.txt"), APRILTAG_NOTICE)?;
    // Cross-check markers.
    let mut readme = format!(
        "# OpenCV-drawn markers\n\n\
         Generated by `cargo xtask dictionaries` with OpenCV {version}: for each predefined\n\
         dictionary, `cv2.aruco.generateImageMarker(dictionary, id, (n + 2) * 10, borderBits=1)`\n\
         for a few ids, saved as `<DICT_NAME>/<id>.png` (10 px a cell, no quiet zone).\n\
         `crates/fiducial/tests/standard_families.rs` renders the same ids with `fiducial` and\n\
         requires identical pixels, then detects each one (on a white margin) with the right id.\n\n\
         Licence: OpenCV is Apache-2.0; the DICT_APRILTAG_* codes are AprilTag's (BSD-2-Clause).\n\
         The notices are in `crates/fiducial/data/families/LICENSE-OpenCV.txt` and\n\
         `LICENSE-AprilTag.txt`.\n\n| dictionary | ids |\n|---|---|\n"
    );
    for d in dicts {
        let src = png_dir.join(&d.name);
        let dst = fixture_dir.join(&d.name);
        std::fs::create_dir_all(&dst)?;
        let mut ids: Vec<u64> = Vec::new();
        for entry in std::fs::read_dir(&src)? {
            let entry = entry?;
            let file = entry.file_name();
            let id = file
                .to_string_lossy()
                .trim_end_matches(".png")
                .parse::<u64>()?;
            ids.push(id);
            std::fs::copy(entry.path(), dst.join(&file))?;
        }
        ids.sort_unstable();
        let ids: Vec<String> = ids.iter().map(u64::to_string).collect();
        readme.push_str(&format!("| {} | {} |\n", d.name, ids.join(", ")));
    }
    std::fs::write(fixture_dir.join("README.md"), readme)?;
    Ok(())
}

/// Every file under `dir`, relative, sorted.
fn files(dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d)? {
            let p = e?.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir)?.to_path_buf());
            }
        }
    }
    out.sort();
    Ok(out)
}

fn compare(fresh: &Path, current: &Path) -> crate::Result {
    let (a, b) = (files(fresh)?, files(current)?);
    if a != b {
        return Err(format!(
            "{}: the set of files differs from a fresh generation; run `cargo xtask dictionaries`",
            current.display()
        )
        .into());
    }
    for f in &a {
        if std::fs::read(fresh.join(f))? != std::fs::read(current.join(f))? {
            return Err(format!(
                "{} is out of date; run `cargo xtask dictionaries`",
                current.join(f).display()
            )
            .into());
        }
    }
    Ok(())
}

pub fn run(args: &[String]) -> crate::Result {
    let check = match args {
        [] => false,
        [flag] if flag == "--check" => true,
        _ => return Err("usage: cargo xtask dictionaries [--check]".into()),
    };
    let root = root();
    let work = root.join("target").join("dictionaries");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work)?;
    let python = crate::pyenv::python(
        &root,
        "dictionaries",
        &[crate::pyenv::OPENCV, crate::pyenv::NUMPY],
        "import cv2, numpy",
    )?;
    let script = work.join("dictionaries.py");
    std::fs::write(&script, SCRIPT)?;
    let json_path = work.join("opencv.json");
    let png_dir = work.join("png");
    crate::pyenv::run_script(&python, &script, &[&json_path, &png_dir])?;
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json_path)?)?;
    let (version, dicts) = parse(&json)?;
    let data_dir = root.join("crates/fiducial/data/families");
    let fixture_dir = root.join("fixtures/markers");
    if check {
        let (d, f) = (work.join("check/families"), work.join("check/markers"));
        write_outputs(&version, &dicts, &png_dir, &d, &f)?;
        compare(&d, &data_dir)?;
        compare(&f, &fixture_dir)?;
        println!(
            "dictionaries: {} and {} are up to date (OpenCV {version})",
            data_dir.display(),
            fixture_dir.display()
        );
    } else {
        let _ = std::fs::remove_dir_all(&fixture_dir);
        write_outputs(&version, &dicts, &png_dir, &data_dir, &fixture_dir)?;
        println!(
            "dictionaries: wrote {} dictionaries (OpenCV {version}) to {} and markers to {}",
            dicts.len(),
            data_dir.display(),
            fixture_dir.display()
        );
    }
    Ok(())
}
