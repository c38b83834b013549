//! Every option's help is a whole sentence: it starts with a capital letter, a backtick,
//! a digit or an option name, never mid-sentence. Regression: when `track`'s shared options
//! moved into their own struct, the first lines of five descriptions were left behind, and
//! `track --help` printed `<INPUT>  rosbag2 folder)` and `--camera <FILE>  CameraInfo`.

#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::process::Command;

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .arg("--help")
        .output()
        .unwrap();
    assert!(out.status.success(), "{args:?} --help failed");
    String::from_utf8(out.stdout).unwrap()
}

/// The subcommands listed by the top-level help.
fn subcommands() -> Vec<String> {
    let top = help(&[]);
    let list = top
        .split("Commands:")
        .nth(1)
        .and_then(|rest| rest.split("Options:").next())
        .unwrap();
    list.lines()
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

/// `(option, first words of its description)` for each option and argument line.
fn descriptions(text: &str) -> Vec<(String, String)> {
    text.lines()
        .filter(|l| {
            let t = l.trim_start();
            l.starts_with("  ") && (t.starts_with('-') || t.starts_with('<'))
        })
        .filter_map(|l| {
            let t = l.trim_start();
            let split = t.find("  ")?;
            let (name, rest) = t.split_at(split);
            Some((name.to_string(), rest.trim_start().to_string()))
        })
        .collect()
}

#[test]
fn every_option_description_starts_a_sentence() {
    let commands = subcommands();
    assert!(commands.len() >= 8, "{commands:?}");
    let mut seen = 0;
    for command in &commands {
        for (option, description) in descriptions(&help(&[command])) {
            seen += 1;
            let first = description.chars().next().unwrap();
            assert!(
                first.is_uppercase() || first.is_ascii_digit() || "`-(".contains(first),
                "`{command} --help`: {option} reads `{description}`"
            );
        }
    }
    assert!(seen > 60, "only {seen} options checked");
}

#[test]
fn track_help_describes_its_input_and_bag_options() {
    let text = help(&["track"]);
    let d = descriptions(&text);
    let of = |name: &str| {
        d.iter()
            .find(|(o, _)| o.starts_with(name))
            .map(|(_, text)| text.clone())
            .unwrap_or_else(|| panic!("no {name} in `track --help`"))
    };
    assert!(of("<INPUT>").starts_with("A folder of images"));
    assert!(of("--camera").starts_with("Camera calibration"));
    assert!(of("--image-topic").starts_with("Bag input: the image topic"));
    assert!(of("--inputs-topic").starts_with("Bag input: the follower's inputs topic"));
    assert!(of("--mcap").starts_with("Also write the results as MCAP"));
}
