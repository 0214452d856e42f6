//! Helpers shared by the daemon's end-to-end and fault tests.
#![allow(dead_code)]

pub mod daemon;
pub mod postgres;

use gtwatch::acquire::register_map::{DataType, FieldSpec, PLANT_TIME_FIELD};
use gtwatch::config::Config;
use gtwatch::plantsim::{PlantFrame, PlantModel, ScriptStep, ScriptTiming, ScriptedPlant};
use gtwatch::signals::Phase;
use std::path::{Path, PathBuf};

/// The reference configuration shipped in `config/gtwatch.toml`.
pub fn reference_config() -> Config {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gtwatch.toml");
    Config::load(&p).expect("config/gtwatch.toml loads")
}

/// The reference config pointed at `endpoint` and `db`, polling fast with short timeouts.
pub fn fast_config(endpoint: &str, db: PathBuf, poll_ms: u64) -> Config {
    let mut c = reference_config();
    c.storage.path = db;
    c.storage.flush_interval_ms = 50;
    let m = c.modbus.as_mut().expect("modbus section");
    m.endpoint = endpoint.to_string();
    c.acquisition.poll_period_ms = poll_ms;
    c.acquisition.connect_timeout_ms = 200;
    c.acquisition.request_timeout_ms = 100;
    c.acquisition.backoff_initial_ms = 20;
    c.acquisition.backoff_max_ms = 100;
    c.daemon.detect_interval_ms = 300;
    assert_eq!(c.check(), vec![], "test config is valid");
    c
}

/// Opens the database read-only for assertions.
pub fn open_db(path: &Path) -> rusqlite::Connection {
    rusqlite::Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .expect("open db")
}

/// (t_ms, value, quality) of one tag, time-ordered.
pub fn tag_samples(db: &rusqlite::Connection, tag: &str) -> Vec<(i64, f64, i64)> {
    let mut st = db
        .prepare(
            "SELECT s.t_ms, s.value, s.quality FROM samples s JOIN tags t ON t.id = s.tag_id
             WHERE t.name = ?1 ORDER BY s.t_ms",
        )
        .expect("prepare");
    st.query_map([tag], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .expect("query")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows")
}

/// (start_ms, end_ms, source, reason) of every gap.
pub fn gaps(db: &rusqlite::Connection) -> Vec<(i64, i64, String, String)> {
    let mut st = db
        .prepare("SELECT start_ms, end_ms, source, reason FROM gaps ORDER BY start_ms")
        .expect("prepare");
    st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .expect("query")
        .collect::<Result<Vec<_>, _>>()
        .expect("rows")
}

/// Plant clock at model time 0 of [`Clocked`] plants (2026-01-05 00:00 UTC).
pub const EPOCH_MS: i64 = 1_767_571_200_000;

/// `c` with the plant clock field `plant_time_ms` appended to the first request and named
/// as `acquisition.timestamp_field`: samples are stamped in plant time, so a plant run faster
/// than real time (and a loaded machine's scheduling stalls) leave the stored spacing exact.
pub fn with_plant_clock(mut c: Config) -> Config {
    let req = &mut c.modbus.as_mut().expect("modbus section").requests[0];
    let next = req
        .fields
        .iter()
        .map(|f| f.address + f.data_type.words())
        .max()
        .expect("the first request has fields");
    req.fields.push(FieldSpec {
        name: PLANT_TIME_FIELD.into(),
        address: next,
        data_type: DataType::F64,
        byte_order: Default::default(),
        scale: 1.0,
        offset: 0.0,
        unit: "ms".into(),
        signal: None,
        min: None,
        max: None,
    });
    c.acquisition.timestamp_field = Some(PLANT_TIME_FIELD.into());
    assert_eq!(c.check(), vec![]);
    c
}

/// A scripted plant with a fixed plant epoch ([`EPOCH_MS`]).
pub struct Clocked(pub ScriptedPlant);

impl PlantModel for Clocked {
    fn step(&mut self) -> PlantFrame {
        self.0.step()
    }
    fn period_s(&self) -> f64 {
        self.0.period_s()
    }
    fn epoch_ms(&self) -> Option<i64> {
        Some(EPOCH_MS)
    }
}

/// Phase timing of the end-to-end script (short phases, plant seconds).
pub fn e2e_timing() -> ScriptTiming {
    ScriptTiming {
        crank_s: 10.0,
        purge_s: 10.0,
        coast_to_light_off_s: 6.0,
        light_off_hold_s: 6.0,
        acceleration_s: 12.0,
        idle_settle_s: 3.0,
        pt_run_up_s: 8.0,
        synchronisation_s: 6.0,
        warmup_ramp_s: 3.0,
        warmup_s: 8.0,
        load_ramp_s: 10.0,
        unloading_s: 10.0,
        coast_down_s: 15.0,
    }
}

/// The end-to-end script: a cold start, a trip in acceleration, a start shut down and restarted
/// hot before the gas generator stops.
pub fn e2e_schedule() -> Vec<ScriptStep> {
    vec![
        ScriptStep::Standstill { duration_s: 15.0 },
        // 1: normal cold start.
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 20.0 },
        ScriptStep::Shutdown { coast_to_rpm: 0.0 },
        ScriptStep::Standstill { duration_s: 80.0 },
        // 2: aborted start (trip during acceleration).
        ScriptStep::AbortedStart {
            trip_in: Phase::Acceleration,
            after_s: 6.0,
        },
        ScriptStep::Standstill { duration_s: 80.0 },
        // 3: normal cold start, then a shutdown restarted before the GG stops.
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 20.0 },
        ScriptStep::Shutdown {
            coast_to_rpm: 900.0,
        },
        // 4: hot restart.
        ScriptStep::Start,
        ScriptStep::Steady { duration_s: 20.0 },
        ScriptStep::Shutdown { coast_to_rpm: 0.0 },
        ScriptStep::Standstill { duration_s: 20.0 },
    ]
}

/// How much longer the fault tests run: `GTWATCH_FAULTS_LONG` unset or `0` → 1 (CI size),
/// `1` → 10, any other whole number n → n. Fault tests multiply their injections (cycles,
/// seeded kill moments) and fault durations by it for soak runs.
pub fn long_factor() -> u32 {
    match std::env::var("GTWATCH_FAULTS_LONG") {
        Err(_) => 1,
        Ok(v) => match v.trim().parse::<u32>() {
            Ok(0) => 1,
            Ok(1) => 10,
            Ok(n) => n,
            Err(_) => panic!("GTWATCH_FAULTS_LONG={v:?}: expected a whole number (1 = ×10)"),
        },
    }
}

/// Outcome of one fault class in one test, printed as one `FAULT-TALLY` line on stderr
/// (`cargo test --test integration faults_x:: -- --nocapture`, collected for the README's table).
#[derive(Debug, Clone)]
pub struct Tally<'a> {
    /// Fault class, e.g. `disk_full_tmpfs`.
    pub class: &'a str,
    /// How many times the fault was injected.
    pub injected: u64,
    /// Committed samples (or results) lost; the test asserts 0 before printing.
    pub lost: u64,
    /// Samples (or results) stored twice; the test asserts 0 before printing.
    pub duplicated: u64,
    /// `PRAGMA integrity_check` after the last injection.
    pub integrity: &'a str,
    /// Anything else worth a column (`gaps=3 dropped_uncommitted=120`), may be empty.
    pub note: String,
}

impl Tally<'_> {
    pub fn print(&self) {
        eprintln!(
            "FAULT-TALLY class={} injected={} lost={} duplicated={} integrity={}{}{}",
            self.class,
            self.injected,
            self.lost,
            self.duplicated,
            self.integrity,
            if self.note.is_empty() { "" } else { " " },
            self.note
        );
    }
}

/// `PRAGMA integrity_check` of the database at `path`, opened read-write as the next `gtwatch`
/// run opens it: a process killed while SQLite still wrote a fresh file in rollback mode (the
/// switch to WAL is itself such a write) leaves a hot `-journal`, which only a writer may roll
/// back; a read-only open refuses it (`SQLITE_READONLY_ROLLBACK`, replay_kill9 in CI once).
pub fn integrity(path: &Path) -> String {
    rusqlite::Connection::open(path)
        .expect("open db")
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .expect("integrity_check")
}

/// Samples stored more than once for the same tag and time (the primary key forbids it;
/// counted anyway for the fault tally).
pub fn duplicate_samples(db: &rusqlite::Connection) -> u64 {
    db.query_row(
        "SELECT COUNT(*) - (SELECT COUNT(*) FROM (SELECT DISTINCT tag_id, t_ms FROM samples))
         FROM samples",
        [],
        |r| r.get::<_, i64>(0),
    )
    .expect("duplicates") as u64
}

/// Diagnosis results stored more than once for the same segment and method.
pub fn duplicate_diagnoses(db: &rusqlite::Connection) -> u64 {
    db.query_row(
        "SELECT COALESCE(SUM(n - 1), 0) FROM
         (SELECT COUNT(*) AS n FROM diagnoses GROUP BY segment_id, method)",
        [],
        |r| r.get::<_, i64>(0),
    )
    .expect("duplicate diagnoses") as u64
}

/// Samples in the database.
pub fn sample_count(db: &rusqlite::Connection) -> u64 {
    db.query_row("SELECT COUNT(*) FROM samples", [], |r| r.get::<_, i64>(0))
        .expect("count") as u64
}

/// Polled samples (`PollStats::samples`) that are not in the database: committed data lost
/// for a daemon that ran to a clean shutdown.
pub fn polled_not_stored(polled: u64, db: &rusqlite::Connection) -> u64 {
    polled.saturating_sub(sample_count(db))
}

/// Uid of `nobody`: root ignores permission bits, so read-only tests run the binary as it.
pub const NOBODY: u32 = 65_534;

/// Whether this process runs as root (effective uid 0).
pub fn running_as_root() -> bool {
    let status = std::fs::read_to_string("/proc/self/status").expect("proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("Uid:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .is_some_and(|euid| euid == "0")
}

/// Sets a file's or directory's permission bits.
pub fn chmod(p: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).expect("chmod");
}

/// One simulated start-up of the reference engine at `health` (noise seeded by `seed`), stored
/// in `db` with good quality and detected: one closed segment, pending diagnosis.
pub fn store_startup(db: &Path, health: &gtwatch::health::HealthParams, seed: u64) {
    use gtwatch::detect::{scan, DetectorConfig};
    use gtwatch::engine::sensors::MeasurementOptions;
    use gtwatch::engine::simulation::run_scenario;
    use gtwatch::engine::{Engine, Scenario, Trace};
    use gtwatch::quality::Quality;
    use gtwatch::signals::Signal;
    use gtwatch::store::{Sample, Store, TagInfo};
    let engine = Engine::reference().expect("engine");
    let (samples, _) =
        run_scenario(&engine.model(health), &Scenario::startup(engine.cfg())).expect("runs");
    let o = MeasurementOptions {
        lags: true,
        noise: true,
        bias: false,
        seed,
    };
    let t = Trace::from_truth(&engine, &samples, Some(&o));
    let mut store = Store::open(db).expect("open");
    let ids: Vec<i64> = Signal::ALL
        .iter()
        .map(|s| store.ensure_tag(&TagInfo::for_signal(*s)).expect("tag"))
        .collect();
    let mut batch = Vec::new();
    for k in 0..t.len() {
        for (i, s) in Signal::ALL.iter().enumerate() {
            let v = t.measured[k][s.index()];
            if v.is_finite() {
                batch.push(Sample {
                    tag: ids[i],
                    t_ms: 1_700_000_000_000 + (t.t_s[k] * 1000.0).round() as i64,
                    value: v,
                    quality: Quality::Good,
                });
            }
        }
    }
    store.insert_samples(&batch).expect("insert");
    scan(&mut store, &DetectorConfig::default()).expect("scan");
}

/// Sends SIGTERM to `child` and waits up to 30 s for it to exit.
pub fn sigterm(child: &mut std::process::Child) -> std::process::ExitStatus {
    use std::time::{Duration, Instant};
    let ok = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(ok.success());
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(s) = child.try_wait().expect("wait") {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "daemon did not stop within 30 s of SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A directory's entries with their sizes, sorted: what a read-only run must leave as it was.
pub fn dir_listing(p: &Path) -> Vec<(String, u64)> {
    let mut v: Vec<(String, u64)> = std::fs::read_dir(p)
        .expect("ls")
        .map(|e| {
            let e = e.expect("entry");
            let len = e.metadata().expect("meta").len();
            (e.file_name().to_string_lossy().into_owned(), len)
        })
        .collect();
    v.sort();
    v
}

/// Start of the first day of a replayed test log, epoch s (2023-11-14).
pub const LOG_T0_S: f64 = 1.7e9;

/// Noisy, lagged instrument traces of `runs` (each a simulated run's true samples), one a day
/// from [`LOG_T0_S`], written as one CSV log at `path` in the `simulate` layout.
pub fn write_daily_log(
    engine: &gtwatch::engine::Engine,
    runs: Vec<(Vec<gtwatch::engine::TruthSample>, u64)>,
    path: &Path,
) {
    use gtwatch::engine::sensors::MeasurementOptions;
    use gtwatch::engine::Trace;
    let mut all: Option<Trace> = None;
    for (day, (samples, seed)) in runs.into_iter().enumerate() {
        let o = MeasurementOptions {
            lags: true,
            noise: true,
            bias: false,
            seed,
        };
        let mut t = Trace::from_truth(engine, &samples, Some(&o));
        let shift = LOG_T0_S + 86_400.0 * day as f64;
        t.t_s.iter_mut().for_each(|x| *x += shift);
        match &mut all {
            None => all = Some(t),
            Some(a) => {
                a.t_s.extend(t.t_s);
                a.phase.extend(t.phase);
                a.truth.extend(t.truth);
                a.measured.extend(t.measured);
            }
        }
    }
    let f = std::fs::File::create(path).expect("create");
    all.expect("at least one run")
        .write_csv(std::io::BufWriter::new(f))
        .expect("write");
}

/// Runs `gtwatch ARGS --config CFG`, asserts that it succeeded (its stderr in the message) and
/// returns its standard output.
pub fn gtwatch_ok(args: &[&str], cfg: &Path) -> Vec<u8> {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gtwatch"))
        .args(args)
        .arg("--config")
        .arg(cfg)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// The shipped config for replaying such a log into `db`: epoch-second `time_s` column,
/// diagnosis on 2 threads.
pub fn replay_config_text(db: &Path) -> String {
    include_str!("../../config/gtwatch.toml")
        .replace(
            "path = \"/var/lib/gtwatch/gtwatch.db\"",
            &format!("path = {:?}", db.display().to_string()),
        )
        .replace("time_column = \"time\"", "time_column = \"time_s\"")
        .replace("time_format = \"iso8601\"", "time_format = \"epoch_s\"")
        .replace("threads = 1", "threads = 2")
}
