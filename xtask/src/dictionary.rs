//! `cargo xtask dictionary [--check]`: regenerates the checked-in marker dictionary
//! `crates/fiducial/data/dict-4x5-d6.txt` from `fiducial::Dictionary::generate` with the
//! paper's parameters. With `--check`, fails instead of writing if the file differs.

use std::path::PathBuf;

use fiducial::{Dictionary, GenerateParams};

/// Path of the checked-in dictionary, from the workspace root.
fn target() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("crates/fiducial/data/dict-4x5-d6.txt")
}

pub fn run(args: &[String]) -> crate::Result {
    let check = match args {
        [] => false,
        [flag] if flag == "--check" => true,
        _ => return Err("usage: cargo xtask dictionary [--check]".into()),
    };
    let dict = Dictionary::generate(&GenerateParams::paper())?;
    let text = dict.to_text();
    let path = target();
    if check {
        let current = std::fs::read_to_string(&path)?;
        if current != text {
            return Err(format!(
                "{} is out of date; run `cargo xtask dictionary`",
                path.display()
            )
            .into());
        }
        println!(
            "dictionary: {} is up to date ({} codes)",
            path.display(),
            dict.len()
        );
    } else {
        std::fs::write(&path, &text)?;
        println!(
            "dictionary: wrote {} codes (4x5, d_min {}) to {}",
            dict.len(),
            dict.min_distance(),
            path.display()
        );
    }
    Ok(())
}
