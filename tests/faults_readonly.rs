//! Fault suite, a read-only database (issue 12 #1): the database file, or the directory that
//! must hold it (and its -wal/-shm files), is not writable. `gtwatch run` and `gtwatch replay`
//! must fail at start, within seconds (no spinning, no retry loop), with a non-zero status and
//! an error naming the database path, and must leave the file and directory as they were.
//!
//! Root ignores permission bits, so when the tests run as root the binary is started as user
//! `nobody` (65534), for whom the files are read-only like for any other user.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use crate::common;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{chmod, running_as_root, NOBODY};

struct Setup {
    _dir: tempfile::TempDir,
    dbdir: PathBuf,
    db: PathBuf,
    run_cfg: PathBuf,
    replay_cfg: PathBuf,
    csv: PathBuf,
}

fn setup() -> Setup {
    let dir = tempfile::tempdir().expect("tempdir");
    // Readable by the user the binary may run as; writable by no one else.
    chmod(dir.path(), 0o755);
    let dbdir = dir.path().join("data");
    std::fs::create_dir(&dbdir).expect("mkdir");
    chmod(&dbdir, 0o755);
    let db = dbdir.join("plant.db");
    let csv = dir.path().join("log.csv");
    std::fs::write(
        &csv,
        "t_ms,n1_rpm\n1700000000000,100\n1700000001000,200\n1700000002000,300\n",
    )
    .expect("csv");
    let replay_cfg = dir.path().join("replay.toml");
    std::fs::write(
        &replay_cfg,
        format!(
            "[storage]\npath = {:?}\n\n[replay]\ntime_column = \"t_ms\"\ntime_format = \"epoch_ms\"\n",
            db.display().to_string()
        ),
    )
    .expect("config");
    let run_cfg = dir.path().join("run.toml");
    let text = include_str!("../config/gtwatch.toml")
        .replace(
            "path = \"/var/lib/gtwatch/gtwatch.db\"",
            &format!("path = {:?}", db.display().to_string()),
        )
        .replace("source = \"modbus\"", "source = \"none\"");
    std::fs::write(&run_cfg, text).expect("config");
    for f in [&csv, &replay_cfg, &run_cfg] {
        chmod(f, 0o644);
    }
    Setup {
        _dir: dir,
        dbdir,
        db,
        run_cfg,
        replay_cfg,
        csv,
    }
}

/// Runs gtwatch with `args` (as `nobody` when root); returns (status, stderr). Fails the test
/// if it is still running after 15 s.
fn gtwatch(args: &[&Path]) -> (std::process::ExitStatus, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_gtwatch"));
    cmd.args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if running_as_root() {
        cmd.uid(NOBODY).gid(NOBODY);
    }
    let mut child = cmd.spawn().expect("spawn gtwatch");
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .expect("stderr")
                .read_to_string(&mut err)
                .expect("read stderr");
            return (status, err);
        }
        if started.elapsed() > Duration::from_secs(15) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("gtwatch {args:?} still running after 15 s on a read-only database");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Creates the database with one good replay (as the current user), so it exists.
fn create_db(s: &Setup) {
    let status = Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(["replay", "--no-detect", "--config"])
        .arg(&s.replay_cfg)
        .arg(&s.csv)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("replay");
    assert!(status.success());
}

fn commands(s: &Setup) -> Vec<(&'static str, Vec<&Path>)> {
    vec![
        (
            "run",
            vec![Path::new("run"), Path::new("--config"), s.run_cfg.as_path()],
        ),
        (
            "replay",
            vec![
                Path::new("replay"),
                Path::new("--no-detect"),
                Path::new("--config"),
                s.replay_cfg.as_path(),
                s.csv.as_path(),
            ],
        ),
    ]
}

/// Opens the database without creating -wal/-shm files (`immutable=1`), so reading it leaves
/// the directory as the commands under test must find and leave it.
fn immutable(db: &Path) -> rusqlite::Connection {
    rusqlite::Connection::open_with_flags(
        format!("file:{}?immutable=1", db.display()),
        rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_URI,
    )
    .expect("open immutable")
}

fn assert_fails_naming_the_db(s: &Setup, what: &str, class: &str) {
    let before = common::dir_listing(&s.dbdir);
    let samples_before = if s.db.exists() {
        common::sample_count(&immutable(&s.db))
    } else {
        0
    };
    for (name, args) in commands(s) {
        let (status, err) = gtwatch(&args);
        assert!(
            !status.success(),
            "{name} on a {what} succeeded; stderr: {err}"
        );
        assert!(
            err.contains(&s.db.display().to_string()),
            "{name} on a {what}: the error does not name the database: {err}"
        );
        assert!(
            !err.contains("panicked"),
            "{name} on a {what} panicked: {err}"
        );
        // One line, and no cause printed twice.
        assert_eq!(err.trim().lines().count(), 1, "{name}: {err}");
        assert_eq!(
            err.matches("readonly database").count().min(1),
            err.matches("readonly database").count(),
            "{name}: {err}"
        );
        assert_eq!(
            common::dir_listing(&s.dbdir),
            before,
            "{name} changed the directory"
        );
    }
    let (lost, integrity) = if s.db.exists() {
        let db = immutable(&s.db);
        let ok: String = db
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .expect("integrity");
        (samples_before.saturating_sub(common::sample_count(&db)), ok)
    } else {
        (0, "ok(no_file)".to_string())
    };
    assert_eq!(lost, 0);
    common::Tally {
        class,
        injected: commands(s).len() as u64,
        lost,
        duplicated: 0,
        integrity: &integrity,
        note: "commands=run,replay exit=nonzero".to_string(),
    }
    .print();
}

#[test]
fn read_only_database_file_fails_at_start_naming_it() {
    let s = setup();
    create_db(&s);
    chmod(&s.db, 0o444);
    assert_fails_naming_the_db(&s, "read-only database file", "readonly_database_file");
}

#[test]
fn read_only_database_directory_fails_at_start_naming_it() {
    let s = setup();
    // No database yet, and the directory that should hold it is read-only.
    chmod(&s.dbdir, 0o555);
    assert_fails_naming_the_db(&s, "read-only directory", "readonly_database_directory");
    assert!(!s.db.exists());
    chmod(&s.dbdir, 0o755);
}
