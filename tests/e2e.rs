//! End-to-end tests: each drives the real `lgdm` binary as a user would.

use std::process::Command;

fn lgdm() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lgdm"))
}

#[test]
fn version_is_printed() {
    let out = lgdm().arg("--version").output().expect("run lgdm");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with("lgdm "), "unexpected: {text}");
}
