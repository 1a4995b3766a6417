//! Every script of `tools/` answers `-h` and `--help` with its usage and does nothing else;
//! `tools/demo` and `tools/colcon-build` hand `--help` on to what they run (`rover demo`, colcon).

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The scripts whose `--help` is the help of the program they wrap.
const HELP_HANDED_ON: [&str; 2] = ["colcon-build", "demo"];
/// The line that makes a script answer `--help` from its header comment.
const HELP_LINE: &str = r#"source "$(dirname "$0")/help.sh""#;

fn tools_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools")
}

/// The executable scripts of `tools/` that answer `--help` themselves.
fn scripts() -> Vec<PathBuf> {
    let mut scripts: Vec<PathBuf> = std::fs::read_dir(tools_dir())
        .expect("read tools/")
        .map(|entry| entry.expect("a tools/ entry").path())
        .filter(|path| path.is_file() && path.metadata().is_ok_and(|m| m.permissions().mode() & 0o111 != 0))
        .filter(|path| !HELP_HANDED_ON.iter().any(|name| path.ends_with(name)))
        .collect();
    scripts.sort();
    scripts
}

/// Whether the script sources the help before its first command (so that `--help` runs nothing).
fn answers_help_first(script: &Path) -> bool {
    let text = std::fs::read_to_string(script).expect("read the script");
    text.lines().skip(1).find(|line| !line.starts_with('#')) == Some(HELP_LINE)
}

#[test]
fn every_script_prints_its_usage_on_help_and_does_nothing_else() {
    let scripts = scripts();
    assert!(scripts.len() >= 9, "the scripts of tools/: {scripts:?}");
    for script in &scripts {
        let name = script.file_name().unwrap().to_string_lossy();
        assert!(answers_help_first(script), "tools/{name}: its first command is not `{HELP_LINE}`");
        for flag in ["-h", "--help"] {
            let output = Command::new("timeout").arg("20").arg(script).arg(flag).output().expect("run the script");
            let usage = String::from_utf8_lossy(&output.stdout);
            assert!(output.status.success(), "tools/{name} {flag}: {:?}", output.status);
            assert!(usage.starts_with(&format!("Usage: tools/{name}")), "tools/{name} {flag}: {usage}");
            assert!(usage.lines().count() >= 2 && !usage.contains("set -euo"), "tools/{name} {flag}: {usage}");
        }
    }
}
