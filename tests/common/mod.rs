//! Helpers shared by the daemon's end-to-end and fault tests.
#![allow(dead_code)]

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
/// (`cargo test --test faults_x -- --nocapture`, collected for the README's table).
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

/// `PRAGMA integrity_check` of the database at `path` (read-only).
pub fn integrity(path: &Path) -> String {
    open_db(path)
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
