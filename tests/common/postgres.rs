//! A real PostgreSQL server for the fleet-sync tests: a fresh cluster in a temporary
//! directory, password authentication (scram-sha-256) on 127.0.0.1 at a free port, stopped in
//! `Drop`. PostgreSQL refuses to run as root: when the tests run as root, initdb and pg_ctl run
//! as the `postgres` user (`runuser`), with the directory handed to that user. The binaries are
//! found on PATH or under /usr/lib/postgresql/*/bin (Debian's `postgresql` package; `.ci/run`
//! installs it).

use std::path::{Path, PathBuf};
use std::process::Command;

/// User and password of the test cluster's superuser.
pub const PG_USER: &str = "gtwatch";
pub const PG_PASSWORD: &str = "fleet-secret";

/// A running (or stopped) test cluster.
pub struct PgServer {
    _dir: tempfile::TempDir,
    data: PathBuf,
    bin: PathBuf,
    pub port: u16,
    as_postgres: bool,
}

/// The directory holding `initdb` and `pg_ctl`, if PostgreSQL is installed.
pub fn pg_bin_dir() -> Option<PathBuf> {
    if let Ok(path) = std::env::var("PATH") {
        for d in std::env::split_paths(&path) {
            if d.join("initdb").is_file() && d.join("pg_ctl").is_file() {
                return Some(d);
            }
        }
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path().join("bin")))
        .filter(|b| b.join("initdb").is_file())
        .collect();
    found.sort();
    found.pop()
}

fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    l.local_addr().expect("addr").port()
}

impl PgServer {
    /// initdb + start. Panics, saying what to install, when PostgreSQL is missing.
    pub fn start() -> PgServer {
        let bin = pg_bin_dir().expect(
            "PostgreSQL not found (initdb on PATH or under /usr/lib/postgresql/*/bin): \
             install the Debian package 'postgresql' (.ci/run does)",
        );
        let dir = tempfile::Builder::new()
            .prefix("gtwatch-pg")
            .tempdir()
            .expect("tempdir");
        let as_postgres = super::running_as_root();
        let data = dir.path().join("data");
        let pwfile = dir.path().join("pw");
        std::fs::write(&pwfile, PG_PASSWORD).expect("pwfile");
        if as_postgres {
            let st = Command::new("chown")
                .args(["-R", "postgres:postgres"])
                .arg(dir.path())
                .status()
                .expect("chown");
            assert!(st.success(), "chown of the test cluster's directory failed");
        }
        let mut server = PgServer {
            _dir: dir,
            data,
            bin,
            port: free_port(),
            as_postgres,
        };
        server.run(
            "initdb",
            &[
                "-D",
                &server.data.display().to_string(),
                "-U",
                PG_USER,
                "--auth=scram-sha-256",
                &format!("--pwfile={}", pwfile.display()),
                "-E",
                "UTF8",
                "--no-sync",
            ],
        );
        server.port = free_port();
        server.start_again();
        server
    }

    /// Runs one of the cluster's programs (as `postgres` when we are root); panics on failure.
    fn run(&self, prog: &str, args: &[&str]) {
        let out = self.command(prog, args).output().expect("spawn");
        assert!(
            out.status.success(),
            "{prog} {args:?} failed: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }

    fn command(&self, prog: &str, args: &[&str]) -> Command {
        let exe = self.bin.join(prog);
        let mut c = if self.as_postgres {
            let mut c = Command::new("runuser");
            c.args(["-u", "postgres", "--"]).arg(&exe);
            c
        } else {
            Command::new(&exe)
        };
        c.args(args).current_dir(std::env::temp_dir());
        c
    }

    /// Starts the (stopped) cluster and waits until it accepts connections.
    pub fn start_again(&self) {
        let opts = format!(
            "-c listen_addresses=127.0.0.1 -c port={} -c unix_socket_directories={} -c fsync=off",
            self.port,
            self.data.display()
        );
        self.run(
            "pg_ctl",
            &[
                "-D",
                &self.data.display().to_string(),
                "-l",
                &self.data.join("log.txt").display().to_string(),
                "-o",
                &opts,
                "-w",
                "-t",
                "60",
                "start",
            ],
        );
    }

    /// Stops the cluster at once (`-m immediate`: like a crash; recovery on the next start).
    pub fn crash(&self) {
        self.run(
            "pg_ctl",
            &[
                "-D",
                &self.data.display().to_string(),
                "-m",
                "immediate",
                "-w",
                "stop",
            ],
        );
    }

    /// Connection URL of database `postgres` as the superuser.
    pub fn url(&self) -> String {
        self.url_with(PG_USER, PG_PASSWORD, "postgres")
    }

    pub fn url_with(&self, user: &str, password: &str, db: &str) -> String {
        format!(
            "postgresql://{user}:{password}@127.0.0.1:{}/{db}",
            self.port
        )
    }

    /// A new empty database on this cluster; its URL.
    pub fn create_db(&self, name: &str) -> String {
        let mut c = postgres::Client::connect(&self.url(), postgres::NoTls).expect("connect");
        c.batch_execute(&format!("CREATE DATABASE {name}"))
            .expect("create db");
        self.url_with(PG_USER, PG_PASSWORD, name)
    }

    pub fn data_dir(&self) -> &Path {
        &self.data
    }
}

impl Drop for PgServer {
    fn drop(&mut self) {
        let _ = self
            .command(
                "pg_ctl",
                &[
                    "-D",
                    &self.data.display().to_string(),
                    "-m",
                    "immediate",
                    "stop",
                ],
            )
            .output();
    }
}
