//! Issue #31: no two modules of the crate import each other. Each module's source (tests
//! included, comments not) is read for the `crate::module` paths it names; a module that
//! names another which names it back fails. Until 2026-12-07 `split`'s unit tests took the
//! light cut's constants from `detector`, which imports `split`.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The modules of `src` that each module's code names (`crate::name`), by module name.
fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut sources = BTreeMap::new();
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "rs") {
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            sources.insert(name, std::fs::read_to_string(&path).unwrap());
        }
    }
    let mut graph = BTreeMap::new();
    for (name, text) in &sources {
        let mut named = BTreeSet::new();
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or("");
            for (i, _) in code.match_indices("crate::") {
                let rest = &code[i + "crate::".len()..];
                let end = rest
                    .find(|c: char| !(c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit()))
                    .unwrap_or(rest.len());
                let target = &rest[..end];
                if target != name && sources.contains_key(target) {
                    named.insert(target.to_string());
                }
            }
        }
        graph.insert(name.clone(), named);
    }
    graph
}

#[test]
fn no_two_modules_import_each_other() {
    let graph = module_graph();
    // The graph is the crate's: the detector names its stages.
    assert!(graph.len() >= 10, "{} modules", graph.len());
    assert!(
        graph["detector"].contains("split"),
        "{:?}",
        graph["detector"]
    );
    let mut both_ways = Vec::new();
    for (a, named) in &graph {
        for b in named {
            if a < b && graph[b].contains(a) {
                both_ways.push(format!("{a} <-> {b}"));
            }
        }
    }
    assert!(
        both_ways.is_empty(),
        "modules importing each other: {both_ways:?}"
    );
}
