//! Issue 12 (security): `gtwatch run` and `check-config` refuse a configuration or database
//! path that other users can write, naming the path and the reason, before touching anything.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use std::os::unix::fs::PermissionsExt;
use std::process::Command;

fn chmod(p: &std::path::Path, mode: u32) {
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
}

#[test]
fn world_writable_config_or_database_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    chmod(dir.path(), 0o755);
    let shipped =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/gtwatch.toml"))
            .unwrap();
    let dbdir = dir.path().join("db");
    std::fs::create_dir(&dbdir).unwrap();
    chmod(&dbdir, 0o755);
    let db = dbdir.join("gtwatch.db");
    let text = shipped.replace(
        "path = \"/var/lib/gtwatch/gtwatch.db\"",
        &format!("path = \"{}\"", db.display()),
    );
    assert_ne!(text, shipped, "shipped storage path not found to replace");
    let cfg = dir.path().join("gtwatch.toml");
    std::fs::write(&cfg, &text).unwrap();

    // World-writable configuration: `run` refuses before opening anything.
    chmod(&cfg, 0o666);
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["run", "--config", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("refusing to start") && err.contains("gtwatch.toml"),
        "{err}"
    );
    assert!(err.contains("writable by every user"), "{err}");
    assert!(!db.exists(), "the database was created before the refusal");
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["check-config", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "check-config accepted a world-writable config"
    );
    chmod(&cfg, 0o644);

    // World-writable database directory (no sticky bit).
    chmod(&dbdir, 0o777);
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["check-config", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{text}");
    assert!(
        text.contains("database") && text.contains("directory holding it"),
        "{text}"
    );
    chmod(&dbdir, 0o755);
    let out = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["check-config", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
