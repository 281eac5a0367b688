//! Every `lgdm …` command line of the docs parses, with clap's whole validation: options and
//! values, required options and conflicts. `crates/pybridge/tests/test_docs.py` runs the docs'
//! runnable examples and checks the others' lines with `--help` appended, which stops at the
//! first unknown option or value but before the required and conflicting ones are checked;
//! this test checks those too. The lines are those of the fenced `sh` blocks of README.md,
//! docs/guide/*.md and docs/reference/*.md, run or not, and of every table of
//! docs/results/reproduce.sh (`--dry-run`).

use std::path::{Path, PathBuf};

use clap::Parser;

use super::Cli;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The text of every fenced block of `page` whose info string starts with `sh`.
fn sh_blocks(page: &Path) -> Vec<(usize, String)> {
    let text = std::fs::read_to_string(page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
    let mut blocks = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((i, line)) = lines.next() {
        let Some(info) = line.strip_prefix("```") else {
            continue;
        };
        let mut body = String::new();
        for (_, line) in lines.by_ref() {
            if line == "```" {
                break;
            }
            body.push_str(line);
            body.push('\n');
        }
        if info.split_whitespace().next() == Some("sh") {
            blocks.push((i + 1, body));
        }
    }
    blocks
}

/// Splits a shell line into words: single and double quotes, backslash escapes, `#` comments.
/// Enough for the docs' command lines, which use nothing else.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word: Option<String> = None;
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '#' if word.is_none() => break,
            ' ' | '\t' => {
                if let Some(w) = word.take() {
                    out.push(w);
                }
            }
            '\'' => {
                let w = word.get_or_insert_with(String::new);
                for c in chars.by_ref() {
                    if c == '\'' {
                        break;
                    }
                    w.push(c);
                }
            }
            '"' => {
                let w = word.get_or_insert_with(String::new);
                while let Some(c) = chars.next() {
                    match c {
                        '"' => break,
                        '\\' => w.extend(chars.next()),
                        c => w.push(c),
                    }
                }
            }
            '\\' => word.get_or_insert_with(String::new).extend(chars.next()),
            c => word.get_or_insert_with(String::new).push(c),
        }
    }
    out.extend(word);
    out
}

/// The argument vector of `line` when it runs `lgdm` (directly, after environment assignments,
/// `time` or a `[ -d DIR ] ||` guard, or as `cargo run … -p lgdm-cli -- …`); `None` otherwise.
fn lgdm_argv(line: &str) -> Option<Vec<String>> {
    let line = match line.split_once("] || ") {
        Some((guard, rest)) if guard.trim_start().starts_with("[ -d ") => rest,
        _ => line,
    };
    let mut w = words(line);
    while w.first().is_some_and(|first| {
        first == "time"
            || first
                .split_once('=')
                .is_some_and(|(name, _)| is_env_name(name))
    }) {
        w.remove(0);
    }
    match w.first().map(String::as_str) {
        Some("lgdm") => Some(w),
        Some("cargo")
            if w.get(1).map(String::as_str) == Some("run")
                && w.windows(2).any(|p| p[0] == "-p" && p[1] == "lgdm-cli") =>
        {
            let dashes = w.iter().position(|x| x == "--")?;
            let mut argv = vec!["lgdm".to_string()];
            argv.extend(w[dashes + 1..].iter().cloned());
            Some(argv)
        }
        _ => None,
    }
}

fn is_env_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c == '_' || c.is_ascii_digit())
}

/// The command lines of a shell text, continuations joined.
fn lines(text: &str) -> Vec<String> {
    text.replace("\\\n", " ")
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(str::to_string)
        .collect()
}

/// Every `lgdm` command of the docs, with where it is.
fn docs_commands() -> Vec<(String, Vec<String>)> {
    let root = repo();
    let mut pages = vec![root.join("README.md")];
    for folder in ["docs/guide", "docs/reference"] {
        let mut found: Vec<PathBuf> = std::fs::read_dir(root.join(folder))
            .unwrap_or_else(|e| panic!("{folder}: {e}"))
            .map(|entry| entry.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        found.sort();
        pages.extend(found);
    }
    let mut commands = Vec::new();
    for page in &pages {
        for (line_no, block) in sh_blocks(page) {
            for line in lines(&block) {
                if let Some(argv) = lgdm_argv(&line) {
                    commands.push((format!("{}:{line_no}", page.display()), argv));
                }
            }
        }
    }
    let script = root.join("docs/results/reproduce.sh");
    let tables = std::process::Command::new("bash")
        .arg(&script)
        .arg("--list")
        .output()
        .expect("bash runs docs/results/reproduce.sh");
    assert!(tables.status.success(), "reproduce.sh --list failed");
    let names: Vec<String> = String::from_utf8_lossy(&tables.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect();
    let printed = std::process::Command::new("bash")
        .arg(&script)
        .arg("--dry-run")
        .args(&names)
        .output()
        .expect("bash runs docs/results/reproduce.sh");
    assert!(printed.status.success(), "reproduce.sh --dry-run failed");
    for line in lines(&String::from_utf8_lossy(&printed.stdout)) {
        if let Some(argv) = lgdm_argv(&line) {
            commands.push(("docs/results/reproduce.sh".to_string(), argv));
        }
    }
    commands
}

#[test]
fn every_lgdm_command_of_the_docs_parses() {
    let commands = docs_commands();
    assert!(
        commands.len() > 50,
        "only {} lgdm commands found in the docs",
        commands.len()
    );
    let failures: Vec<String> = commands
        .iter()
        .filter_map(|(place, argv)| {
            Cli::try_parse_from(argv)
                .err()
                .map(|e| format!("{place}: {}\n{e}", argv.join(" ")))
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_splitter_reads_the_docs_quoting() {
    assert_eq!(
        lgdm_argv("OMP_NUM_THREADS=1 lgdm sim grasp --out 'a b' # note"),
        Some(
            vec!["lgdm", "sim", "grasp", "--out", "a b"]
                .into_iter()
                .map(String::from)
                .collect()
        )
    );
    assert_eq!(
        lgdm_argv("[ -d ycb ] || lgdm sim objects --out ycb/").map(|a| a.len()),
        Some(5)
    );
    assert_eq!(
        lgdm_argv("cargo run --release -p lgdm-cli -- train --scenario ni"),
        Some(
            vec!["lgdm", "train", "--scenario", "ni"]
                .into_iter()
                .map(String::from)
                .collect()
        )
    );
    assert_eq!(lgdm_argv("python -m lgdm.sweep x.toml"), None);
    // A block's continuation lines are one command.
    assert_eq!(
        lines("lgdm sim grasp \\\n  --rounds 1\n# c\n"),
        ["lgdm sim grasp    --rounds 1"]
    );
}
