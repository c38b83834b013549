//! `cargo xtask unused-deps`: fail when a workspace crate declares a dependency its code
//! never names.
//!
//! For every workspace package (from `cargo metadata`), each `[dependencies]` entry must be
//! named in the package's library or binary sources (`src/`, `build.rs`), and each
//! `[dev-dependencies]` entry in its tests, benches, examples or `src/` (unit tests). "Named"
//! means a path (`name::`), a `use name` or an `extern crate name` outside a `//` comment,
//! with the dependency's Rust name (its rename, else its package name with `-` as `_`).
//! This is a text check, not a compiler pass: it catches the usual case, a dependency left
//! behind when the code that used it moved to another crate.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::Result;

/// One dependency that no source names.
#[derive(Debug, PartialEq)]
struct Unused {
    package: String,
    dependency: String,
    kind: &'static str,
}

pub fn run(args: &[String]) -> Result {
    if let Some(extra) = args.first() {
        return Err(format!("unused-deps takes no arguments, got {extra}").into());
    }
    let meta: Value = crate::cargo_metadata(&["--no-deps"])?;
    let packages = meta["packages"]
        .as_array()
        .ok_or("cargo metadata: no `packages` array")?;
    let mut unused = Vec::new();
    for package in packages {
        unused.extend(check_package(package)?);
    }
    if unused.is_empty() {
        println!(
            "unused-deps: every dependency of the {} workspace packages is used",
            packages.len()
        );
        return Ok(());
    }
    for u in &unused {
        eprintln!(
            "unused-deps: {} declares {} dependency `{}` but no source names it",
            u.package, u.kind, u.dependency
        );
    }
    Err(format!("{} unused dependencies (see above)", unused.len()).into())
}

fn check_package(package: &Value) -> Result<Vec<Unused>> {
    let name = package["name"].as_str().unwrap_or("?").to_string();
    let manifest = PathBuf::from(
        package["manifest_path"]
            .as_str()
            .ok_or("cargo metadata: package without manifest_path")?,
    );
    let root = manifest.parent().ok_or("manifest without a folder")?;
    let normal_src = read_sources(&[root.join("src"), root.join("build.rs")])?;
    let dev_src = read_sources(&[
        root.join("src"),
        root.join("tests"),
        root.join("benches"),
        root.join("examples"),
    ])?;
    let mut unused = Vec::new();
    for dep in package["dependencies"].as_array().into_iter().flatten() {
        let rust_name = dep["rename"]
            .as_str()
            .or(dep["name"].as_str())
            .unwrap_or("")
            .replace('-', "_");
        let (kind, sources) = match dep["kind"].as_str() {
            None => ("normal", &normal_src),
            Some("dev") => ("dev", &dev_src),
            // Build dependencies are named in build.rs, which `normal_src` reads.
            Some(_) => ("build", &normal_src),
        };
        if !sources.iter().any(|text| names(text, &rust_name)) {
            let dev_only = kind == "normal" && dev_src.iter().any(|text| names(text, &rust_name));
            unused.push(Unused {
                package: name.clone(),
                dependency: rust_name,
                kind: if dev_only {
                    "normal (only tests, benches or examples name it: make it a dev-dependency)"
                } else {
                    kind
                },
            });
        }
    }
    Ok(unused)
}

/// The text of every `.rs` file under `paths` (files or folders; missing ones are skipped).
fn read_sources(paths: &[PathBuf]) -> Result<Vec<String>> {
    let mut texts = Vec::new();
    for path in paths {
        collect(path, &mut texts)?;
    }
    Ok(texts)
}

fn collect(path: &Path, texts: &mut Vec<String>) -> Result {
    if path.is_file() {
        if path.extension().is_some_and(|e| e == "rs") {
            texts.push(std::fs::read_to_string(path)?);
        }
    } else if path.is_dir() {
        for entry in std::fs::read_dir(path)? {
            collect(&entry?.path(), texts)?;
        }
    }
    Ok(())
}

/// Whether `text` names the crate `ident` in code: `ident::`, `use ident` or
/// `extern crate ident`, starting at a word boundary, on a line that is not a `//` comment.
fn names(text: &str, ident: &str) -> bool {
    text.lines()
        .filter(|line| !line.trim_start().starts_with("//"))
        .any(|line| {
            line.match_indices(ident).any(|(at, _)| {
                let before = line[..at].chars().next_back();
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    return false;
                }
                let after = &line[at + ident.len()..];
                let prefix = line[..at].trim_end();
                after.starts_with("::")
                    || ((prefix.ends_with("use") || prefix.ends_with("extern crate"))
                        && after
                            .chars()
                            .next()
                            .is_none_or(|c| !(c.is_alphanumeric() || c == '_')))
            })
        })
}

#[cfg(test)]
mod tests {
    use super::names;

    #[test]
    fn paths_uses_and_extern_crates_count_comments_and_longer_names_do_not() {
        assert!(names("let x = rand::random();", "rand"));
        assert!(names("use rand_chacha::ChaCha8Rng;", "rand_chacha"));
        assert!(names("    use serde;", "serde"));
        assert!(names("extern crate criterion;", "criterion"));
        assert!(names("#[derive(serde::Serialize)]", "serde"));
        assert!(!names("use rand_chacha::ChaCha8Rng;", "rand"));
        assert!(!names("// rand::random()", "rand"));
        assert!(!names("let operand::x = 1;", "rand"));
        assert!(!names("let brand = 1;", "rand"));
        assert!(!names("std::rand::x", "rand"));
    }
}
