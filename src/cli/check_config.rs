//! `gtwatch check-config FILE`: parse and check a configuration, explaining every problem.
//!
//! Exit status 0 when the file is valid, 1 otherwise. Reads the file only.

use crate::acquire::register_map::REQUIRED_SIGNALS;
use crate::config::Config;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct CheckConfigArgs {
    /// Configuration file to check.
    pub file: PathBuf,
}

/// The report printed by `check-config` (separate from printing so tests can check it).
pub(super) fn report(file: &std::path::Path) -> (bool, String) {
    let shown = file.display().to_string();
    let cfg = match Config::load(file) {
        Ok(c) => c,
        Err(e) => return (false, format!("{e}\n")),
    };
    let problems = cfg.check();
    if !problems.is_empty() {
        let mut out = format!("{shown}: {} problem(s)\n", problems.len());
        for p in &problems {
            out.push_str(&format!("  {}: {}\n", p.key, p.message));
        }
        return (false, out);
    }
    let findings = crate::permissions::check_daemon_paths(
        file,
        cfg.plant.engine_model.as_deref(),
        &cfg.storage.path,
        crate::permissions::current_uid(),
    );
    let refused: Vec<_> = findings
        .iter()
        .filter(|f| f.severity == crate::permissions::Severity::Refuse)
        .collect();
    if !refused.is_empty() {
        let mut out = format!(
            "{shown}: {} permission problem(s); `gtwatch run` refuses to start\n",
            refused.len()
        );
        for f in refused {
            out.push_str(&format!("  {f}\n"));
        }
        return (false, out);
    }
    let mut out = format!("{shown}: OK — plant '{}'\n", cfg.plant.name);
    for f in &findings {
        out.push_str(&format!("  warning: {f}\n"));
    }
    out.push_str(&format!("  storage: {}\n", cfg.storage.path.display()));
    let d = &cfg.detector;
    out.push_str(&format!(
        "  detector: purge {:.0}, light-off {:.0}, idle {:.0}, PT {:.0} rpm, base load {} MW ({})\n",
        d.purge_speed_rpm,
        d.light_off_speed_rpm,
        d.idle_speed_rpm,
        d.pt_sync_speed_rpm,
        d.base_load_mw,
        match &cfg.plant.engine_model {
            Some(m) => format!("engine file {} unless [detector] sets them", m.display()),
            None => "the built-in engine's unless [detector] sets them".to_string(),
        }
    ));
    match &cfg.modbus {
        Some(m) => {
            let tags = m.fields().count();
            out.push_str(&format!(
                "  modbus: {} every {} ms, {} request(s), {} tag(s)\n",
                m.endpoint,
                cfg.acquisition.poll_period_ms,
                m.requests.len(),
                tags
            ));
            for (_, f) in m.fields() {
                let sig = f.signal.map(|s| s.short()).unwrap_or("-");
                out.push_str(&format!(
                    "    {:<14} {:>5} {:<4} {:<4} {:<10} {}\n",
                    f.name,
                    f.address,
                    f.data_type.to_string(),
                    format!("{:?}", f.byte_order),
                    sig,
                    f.unit
                ));
            }
            let req: Vec<&str> = REQUIRED_SIGNALS.iter().map(|s| s.short()).collect();
            out.push_str(&format!("  required signals present: {}\n", req.join(", ")));
        }
        None => out.push_str("  no live acquisition (acquisition.source = \"none\")\n"),
    }
    (true, out)
}

pub(super) fn run(args: CheckConfigArgs) -> anyhow::Result<ExitCode> {
    let (ok, text) = report(&args.file);
    if ok {
        print!("{text}");
        Ok(ExitCode::SUCCESS)
    } else {
        eprint!("{text}");
        Ok(ExitCode::FAILURE)
    }
}
