//! The daemon's configuration file (`config/gtwatch.toml`): parsing and checking.
//!
//! Parsing is strict (`deny_unknown_fields` everywhere): a misspelt key is an error naming the
//! file, line and column. [`Config::check`] then collects every semantic problem at once (each
//! naming its key path and the reason), so `gtwatch check-config` can list them all. The
//! sections `[storage]`, `[replay]` and `[detector]` belong to the data side (`store`, `replay`,
//! `detect`); their own `validate` is called here. This module reads the file and nothing else.

use crate::acquire::modbus::{AcquisitionConfig, SourceKind};
use crate::acquire::register_map::ModbusConfig;
use crate::config_problem::{check_range, Bounds, ConfigProblem};
use crate::detect::DetectorConfig;
use crate::ingest::ReplayConfig;
use crate::store::StorageConfig;
use crate::worker::DiagnosisSettings;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The whole configuration file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub plant: PlantConfig,
    #[serde(default)]
    pub storage: StorageConfig,
    #[serde(default)]
    pub replay: ReplayConfig,
    /// `[quality]`: the bad-value policy (ranges, stuck sensors, spikes).
    #[serde(default)]
    pub quality: crate::quality::QualityConfig,
    #[serde(default)]
    pub detector: DetectorConfig,
    #[serde(default)]
    pub acquisition: AcquisitionConfig,
    /// Required when `acquisition.source = "modbus"`.
    #[serde(default)]
    pub modbus: Option<ModbusConfig>,
    #[serde(default)]
    pub daemon: DaemonConfig,
    #[serde(default)]
    pub diagnosis: DiagnosisSettings,
    /// `[wash]`: prices and limits of the wash advice (see `wash::WashEconomics`).
    #[serde(default)]
    pub wash: crate::wash::WashEconomics,
    /// `[metrics]`: the optional Prometheus endpoint.
    #[serde(default)]
    pub metrics: MetricsConfig,
    /// `[fleet]`: the optional sync to a central PostgreSQL (see `fleet::FleetConfig`).
    #[serde(default)]
    pub fleet: Option<crate::fleet::FleetConfig>,
}

/// `[metrics]`: the Prometheus endpoint (`GET /metrics`), off unless `listen` is set.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsConfig {
    /// Address and port to serve on, e.g. `"127.0.0.1:9464"` (an IP literal; port 0 = any
    /// free port, logged). Absent: no endpoint.
    pub listen: Option<String>,
    /// Allow an address other than loopback. Off: the daemon sits beside a control system,
    /// whose network must not gain a listening port by accident; a remote Prometheus should
    /// scrape through a proxy or an SSH tunnel, or this is set deliberately.
    pub allow_remote: bool,
}

impl MetricsConfig {
    /// The address to serve on, if any (`None` also when `listen` does not parse: `validate`
    /// reports that).
    pub fn addr(&self) -> Option<std::net::SocketAddr> {
        self.listen.as_deref().and_then(|l| l.parse().ok())
    }

    pub fn validate(&self) -> Vec<ConfigProblem> {
        let Some(listen) = self.listen.as_deref() else {
            return Vec::new();
        };
        match listen.parse::<std::net::SocketAddr>() {
            Err(_) => vec![ConfigProblem::new(
                "metrics.listen",
                format!("'{listen}' is not an IP address and port such as \"127.0.0.1:9464\""),
            )],
            Ok(a) if !a.ip().is_loopback() && !self.allow_remote => vec![ConfigProblem::new(
                "metrics.listen",
                format!(
                    "{a} is not a loopback address: the daemon runs beside a control system, so \
                     the endpoint stays on 127.0.0.1/::1 unless metrics.allow_remote = true"
                ),
            )],
            Ok(_) => Vec::new(),
        }
    }
}

/// `[plant]`: which machine this is and the engine model used to diagnose it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantConfig {
    /// Free-text plant / unit name, used in logs and reports.
    pub name: String,
    /// Engine model parameter file; relative paths are relative to the config file. Optional
    /// until diagnosis runs in the daemon: the built-in reference engine is used without it.
    #[serde(default)]
    pub engine_model: Option<PathBuf>,
}

/// `[daemon]`: how the daemon schedules its tasks.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonConfig {
    /// Run the start-up detector over new samples every this many ms. Default 10 000.
    pub detect_interval_ms: u64,
    /// Poll results buffered between acquisition and the writer. Default 1024.
    pub queue_capacity: usize,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig {
            detect_interval_ms: 10_000,
            queue_capacity: 1024,
        }
    }
}

/// Reading or parsing the file failed.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        path: String,
        line: usize,
        column: usize,
        message: String,
    },
    /// The file parsed but `check()` found problems (used by callers that refuse to start).
    #[error("{path}: {} problem(s):\n  {}", problems.len(), problems.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n  "))]
    Invalid {
        path: String,
        problems: Vec<ConfigProblem>,
    },
}

/// 1-based line and column of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before
        .rfind('\n')
        .map_or(before.len(), |i| before.len() - i - 1)
        + 1;
    (line, col)
}

impl Config {
    /// Parses `text` (named `path` in errors). Relative paths are left as written.
    pub fn parse(text: &str, path: &str) -> Result<Config, ConfigError> {
        toml::from_str(text).map_err(|e: toml::de::Error| {
            let (line, column) = e.span().map_or((0, 0), |s| line_col(text, s.start));
            ConfigError::Parse {
                path: path.to_string(),
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })
    }

    /// Reads and parses the file; relative `storage.path` and `plant.engine_model` are
    /// resolved against the file's directory, and the `[detector]` engine speeds it does not
    /// set are the engine file's. Does not run [`Config::check`].
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: shown.clone(),
            source,
        })?;
        let mut cfg = Config::parse(&text, &shown)?;
        if let Some(dir) = path.parent() {
            if cfg.storage.path.is_relative() {
                cfg.storage.path = dir.join(&cfg.storage.path);
            }
            if let Some(m) = cfg.plant.engine_model.as_mut() {
                if m.is_relative() {
                    *m = dir.join(&*m);
                }
            }
        }
        // The detector's engine speeds come from the engine file unless `[detector]` sets them.
        // An engine file that does not load leaves the built-in engine's: `check` and the
        // daemon's own loading of the engine report it.
        if let Ok(engine) = crate::engine::config::EngineConfig::load_or_reference(
            cfg.plant.engine_model.as_deref(),
        ) {
            let raw: Option<toml::Table> = toml::from_str(&text).ok();
            let section = raw.as_ref().and_then(|t| t.get("detector"));
            cfg.detector.fill_from_engine(section, &engine);
        }
        Ok(cfg)
    }

    /// Loads and checks; any problem is an error (what `run` uses).
    pub fn load_checked(path: &Path) -> Result<Config, ConfigError> {
        let cfg = Config::load(path)?;
        let problems = cfg.check();
        if problems.is_empty() {
            Ok(cfg)
        } else {
            Err(ConfigError::Invalid {
                path: path.display().to_string(),
                problems,
            })
        }
    }

    /// Every problem in the configuration (empty = valid), in file order of sections.
    pub fn check(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        if self.plant.name.trim().is_empty() {
            p.push(ConfigProblem::new("plant.name", "must not be empty"));
        }
        if let Some(m) = &self.plant.engine_model {
            if !m.is_file() {
                p.push(ConfigProblem::new(
                    "plant.engine_model",
                    format!("file {} not found", m.display()),
                ));
            }
        }
        p.extend(self.storage.validate());
        p.extend(self.replay.validate());
        p.extend(self.quality.validate());
        p.extend(self.detector.validate());
        p.extend(self.acquisition.validate());
        p.extend(self.diagnosis.validate());
        if let Err(e) = self.wash.validate() {
            p.push(ConfigProblem::new("wash", e));
        }
        p.extend(self.metrics.validate());
        if let Some(f) = &self.fleet {
            p.extend(f.validate());
        }
        match (&self.modbus, self.acquisition.source) {
            (Some(m), _) => {
                p.extend(m.check());
                // Detector inputs named explicitly must exist in the register map.
                let names: Vec<&str> = m.fields().map(|(_, f)| f.name.as_str()).collect();
                for (key, tag) in [
                    ("n1_tag", &self.detector.n1_tag),
                    ("fuel_tag", &self.detector.fuel_tag),
                    ("power_tag", &self.detector.power_tag),
                    ("n2_tag", &self.detector.n2_tag),
                ] {
                    if let Some(t) = tag {
                        if !names.contains(&t.as_str()) {
                            p.push(ConfigProblem::new(
                                format!("detector.{key}"),
                                format!("tag '{t}' is not a field of the register map"),
                            ));
                        }
                    }
                }
                if let Some(t) = &self.acquisition.timestamp_field {
                    match m.fields().find(|(_, f)| &f.name == t) {
                        None => p.push(ConfigProblem::new(
                            "acquisition.timestamp_field",
                            format!("'{t}' is not a field of the register map"),
                        )),
                        Some((_, f)) if f.signal.is_some() => p.push(ConfigProblem::new(
                            "acquisition.timestamp_field",
                            format!("'{t}' feeds an engine signal; the clock needs its own field"),
                        )),
                        Some(_) => {}
                    }
                }
            }
            (None, SourceKind::Modbus) => p.push(ConfigProblem::new(
                "modbus",
                "acquisition.source = \"modbus\" needs a [modbus] section with the register map",
            )),
            (None, SourceKind::None) => {}
        }
        check_range(
            &mut p,
            "daemon.detect_interval_ms",
            self.daemon.detect_interval_ms,
            Bounds {
                lo: 100,
                hi: 86_400_000,
                unit: " ms",
                why: "100 ms … 1 day",
            },
        );
        check_range(
            &mut p,
            "daemon.queue_capacity",
            self.daemon.queue_capacity as u64,
            Bounds {
                lo: 1,
                hi: 1_000_000,
                unit: "",
                why: "messages between acquisition and the writer; each takes memory",
            },
        );
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_detectors_engine_speeds_come_from_the_engine_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let md22 = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/engine_md22.toml");
        let text = include_str!("../config/gtwatch.toml").replace(
            "# engine_model = \"engine.toml\"",
            &format!("engine_model = {:?}", md22.display().to_string()),
        );
        let path = dir.path().join("gtwatch.toml");
        std::fs::write(&path, &text).expect("write");
        let cfg = Config::load(&path).expect("loads");
        let d = &cfg.detector;
        assert_eq!((d.idle_speed_rpm, d.pt_sync_speed_rpm), (6600.0, 6500.0));
        assert_eq!(d.base_load_mw, 22.0);
        // One the section sets stays; without an engine file they are the built-in engine's.
        std::fs::write(
            &path,
            text.replace("[detector]\n", "[detector]\nidle_speed_rpm = 6000.0\n"),
        )
        .expect("write");
        let d = Config::load(&path).expect("loads").detector;
        assert_eq!((d.idle_speed_rpm, d.pt_sync_speed_rpm), (6000.0, 6500.0));
        std::fs::write(&path, include_str!("../config/gtwatch.toml")).expect("write");
        assert_eq!(
            Config::load(&path).expect("loads").detector,
            DetectorConfig::default()
        );
    }

    /// The shipped reference file claims to list the defaults: each section it sets must equal
    /// what the code uses when the section (or key) is left out.
    #[test]
    fn shipped_config_lists_the_code_defaults() {
        let text = include_str!("../config/gtwatch.toml");
        let shipped = Config::parse(text, "config/gtwatch.toml").expect("shipped config parses");
        assert_eq!(shipped.storage, StorageConfig::default(), "[storage]");
        assert_eq!(shipped.replay, ReplayConfig::default(), "[replay]");
        assert_eq!(shipped.detector, DetectorConfig::default(), "[detector]");
        assert_eq!(
            shipped.quality,
            crate::quality::QualityConfig::default(),
            "[quality]"
        );
        assert_eq!(
            shipped.acquisition,
            AcquisitionConfig::default(),
            "[acquisition]"
        );
        assert_eq!(shipped.daemon, DaemonConfig::default(), "[daemon]");
        assert_eq!(
            shipped.diagnosis,
            DiagnosisSettings::default(),
            "[diagnosis]"
        );
        assert_eq!(
            shipped.wash,
            crate::wash::WashEconomics::default(),
            "[wash]"
        );
        assert_eq!(shipped.metrics, MetricsConfig::default(), "[metrics]");
        assert_eq!(shipped.fleet, None, "[fleet] is off unless configured");
        assert!(shipped.check().is_empty(), "{:?}", shipped.check());
        // Every key of those sections is written out in the file (none left to a hidden default).
        let table: toml::Table = toml::from_str(text).expect("toml");
        for (section, n_keys) in [
            ("storage", 11),
            ("acquisition", 7),
            ("daemon", 2),
            ("diagnosis", 14),
            ("quality", 2),
            ("wash", 8),
        ] {
            let t = table
                .get(section)
                .and_then(|v| v.as_table())
                .unwrap_or_else(|| panic!("[{section}] missing"));
            assert_eq!(
                t.len(),
                n_keys,
                "[{section}] keys: {:?}",
                t.keys().collect::<Vec<_>>()
            );
        }
    }

    /// `[metrics] listen` must be an IP and port; a non-loopback one needs `allow_remote`.
    #[test]
    fn metrics_listen_is_loopback_unless_allowed() {
        let with = |extra: &str| {
            Config::parse(&format!("{MINIMAL}\n[metrics]\n{extra}\n"), "x.toml")
                .expect("parse")
                .check()
                .iter()
                .map(|p| p.to_string())
                .filter(|p| p.starts_with("metrics"))
                .collect::<Vec<_>>()
        };
        assert!(with("listen = \"127.0.0.1:9464\"").is_empty());
        assert!(with("listen = \"[::1]:0\"").is_empty());
        let remote = with("listen = \"0.0.0.0:9464\"");
        assert_eq!(remote.len(), 1, "{remote:?}");
        assert!(remote[0].contains("metrics.listen") && remote[0].contains("allow_remote"));
        assert!(with("listen = \"0.0.0.0:9464\"\nallow_remote = true").is_empty());
        let bad = with("listen = \"localhost:9464\"");
        assert!(
            bad.len() == 1 && bad[0].contains("metrics.listen"),
            "{bad:?}"
        );
        assert_eq!(
            Config::parse(MINIMAL, "x.toml")
                .expect("parse")
                .metrics
                .addr(),
            None
        );
    }

    /// `[fleet]`: absent in the shipped file (no sync); bad values name the key and why.
    #[test]
    fn fleet_section_is_checked_key_by_key() {
        let with = |extra: &str| {
            Config::parse(&format!("{MINIMAL}\n[fleet]\n{extra}\n"), "x.toml")
                .expect("parse")
                .check()
                .iter()
                .map(|p| p.to_string())
                .filter(|p| p.starts_with("fleet"))
                .collect::<Vec<_>>()
        };
        let good = "unit_id = \"gt-1\"\npostgres_url = \"postgresql://u:p@127.0.0.1:5432/fleet\"";
        assert!(with(good).is_empty(), "{:?}", with(good));
        let cfg = Config::parse(&format!("{MINIMAL}\n[fleet]\n{good}\n"), "x.toml").expect("parse");
        let f = cfg.fleet.expect("fleet");
        assert_eq!(
            (f.interval_s, f.send_samples, f.batch_rows),
            (60, true, 5000)
        );
        assert!(Config::parse(MINIMAL, "x.toml")
            .expect("parse")
            .fleet
            .is_none());
        let bad = with(
            "unit_id = \"gt 1\"\npostgres_url = \"postgresql://u@h:notaport/x\"\ninterval_s = 0\nbatch_rows = 0",
        );
        assert_eq!(bad.len(), 4, "{bad:?}");
        for key in [
            "fleet.unit_id",
            "fleet.postgres_url",
            "fleet.interval_s",
            "fleet.batch_rows",
        ] {
            assert!(bad.iter().any(|p| p.contains(key)), "{key}: {bad:?}");
        }
        assert!(bad.iter().any(|p| p.contains("contains ' '")), "{bad:?}");
        assert!(
            Config::parse(&format!("{MINIMAL}\n[fleet]\nunit_id = \"x\"\n"), "x.toml").is_err()
        );
    }

    /// Leaving out `[acquisition]` gives the documented 10 Hz poll.
    #[test]
    fn missing_acquisition_section_polls_at_100_ms() {
        let text = MINIMAL.replace("[acquisition]\npoll_period_ms = 100\n", "");
        assert!(!text.contains("[acquisition]"));
        let c = Config::parse(&text, "x.toml").expect("parse");
        assert_eq!(c.acquisition.poll_period_ms, 100);
    }

    const MINIMAL: &str = r#"
[plant]
name = "GT1"

[storage]
path = "gt.db"

[acquisition]
poll_period_ms = 100

[modbus]
endpoint = "127.0.0.1:5020"

[[modbus.request]]
slave_id = 1
register = "holding"
start_address = 0

[[modbus.request.field]]
name = "n1_rpm"
address = 0
type = "f32"
signal = "n1"
"#;

    #[test]
    fn unknown_keys_name_file_line_and_column() {
        let text = MINIMAL.replace(
            "poll_period_ms = 100",
            "poll_period_ms = 100\npoll_perod = 5",
        );
        let e = Config::parse(&text, "x.toml").expect_err("unknown key");
        let s = e.to_string();
        assert!(
            s.starts_with("x.toml:10:1: unknown field `poll_perod`"),
            "{s}"
        );
        let text = MINIMAL.replace("type = \"f32\"", "type = \"float\"");
        let s = Config::parse(&text, "x.toml")
            .expect_err("bad type")
            .to_string();
        assert!(s.starts_with("x.toml:22:8: unknown variant `float`"), "{s}");
    }

    #[test]
    fn check_lists_problems_from_every_section() {
        let mut c = Config::parse(MINIMAL, "x.toml").expect("parse");
        c.storage.batch_size = 0;
        c.acquisition.backoff_max_ms = 1;
        c.detector.n1_tag = Some("nope".into());
        let keys: Vec<String> = c.check().into_iter().map(|p| p.key).collect();
        assert_eq!(
            keys,
            vec![
                "storage.batch_size",
                "acquisition.backoff_max_ms",
                "modbus.request", // missing required signals
                "detector.n1_tag",
            ]
        );
        c.modbus = None;
        let keys: Vec<String> = c.check().into_iter().map(|p| p.key).collect();
        assert!(keys.contains(&"modbus".to_string()));
    }

    #[test]
    fn values_that_crashed_the_daemon_are_rejected_with_their_key() {
        // Regression (issue 12 #4): check-config accepted these; the daemon then panicked or
        // aborted at start-up (a restart loop under systemd).
        let mut c = Config::parse(MINIMAL, "x.toml").expect("parse");
        c.storage.busy_timeout_ms = 2_147_483_648;
        c.daemon.queue_capacity = usize::MAX;
        c.storage.batch_size = 10_000_000_000;
        c.replay.transaction_samples = 10_000_000_000;
        let problems = c.check();
        let keys: Vec<&str> = problems.iter().map(|p| p.key.as_str()).collect();
        for k in [
            "storage.batch_size",
            "storage.busy_timeout_ms",
            "replay.transaction_samples",
            "daemon.queue_capacity",
        ] {
            assert!(keys.contains(&k), "{k} missing from {problems:?}");
        }
        let busy = problems
            .iter()
            .find(|p| p.key == "storage.busy_timeout_ms")
            .expect("busy");
        assert!(
            busy.message.contains("2147483648 ms is above the maximum"),
            "{busy}"
        );
    }

    #[test]
    fn line_col_is_one_based() {
        assert_eq!(line_col("ab\ncd", 0), (1, 1));
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
    }
}
