//! File-permission checks for what the daemon trusts: its configuration, the engine file it
//! loads, and the database it writes.
//!
//! Whoever can write the configuration can point the daemon at another Modbus endpoint or
//! another database, and whoever can write the database can rewrite the degradation history
//! the wash advice is based on. So `gtwatch run` refuses to start when such a path, or the
//! directory holding it, is writable by users other than its owner (world-writable, or
//! owned by a user who is neither the daemon's user nor root), and says which path and why.
//! Group-writable paths are allowed (a `gtwatch` group is a normal deployment) but reported by
//! `check-config` as a warning.
//!
//! Reads metadata only; never changes a permission itself (fixing it is the operator's call).

use std::fmt;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// What a path is to the daemon (named in messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    Config,
    EngineFile,
    Database,
    DatabaseDirectory,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::Config => "configuration file",
            Role::EngineFile => "engine file",
            Role::Database => "database",
            Role::DatabaseDirectory => "database directory",
        })
    }
}

/// How bad a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Severity {
    /// Allowed, but worth knowing (group-writable).
    Warning,
    /// The daemon refuses to start.
    Refuse,
}

/// One permission problem.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Finding {
    pub(crate) path: PathBuf,
    pub(crate) role: Role,
    pub(crate) severity: Severity,
    pub(crate) reason: String,
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}: {}", self.role, self.path.display(), self.reason)
    }
}

/// The user the checks are made for (the daemon's effective user).
pub(crate) fn current_uid() -> u32 {
    // The effective uid of this process is the owner of files it creates; reading it from a
    // file we just made would need I/O and a writable place, /proc/self is always there on
    // Linux and owned by the process's uid.
    std::fs::metadata("/proc/self").map_or(0, |m| m.uid())
}

/// Checks one path (if it exists) and the directory holding it.
///
/// A directory with the sticky bit (`/tmp`) is not treated as writable by others for the
/// files in it: others cannot replace a file they do not own there.
pub(crate) fn check_path(path: &Path, role: Role, uid: u32) -> Vec<Finding> {
    let mut out = Vec::new();
    if let Ok(meta) = std::fs::metadata(path) {
        judge(path, role, &meta, uid, &mut out);
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if let Ok(meta) = std::fs::metadata(dir) {
        let sticky = meta.mode() & 0o1000 != 0;
        if !sticky {
            let dir_role = match role {
                Role::Database | Role::DatabaseDirectory => Role::DatabaseDirectory,
                other => other,
            };
            let mut dir_findings = Vec::new();
            judge(dir, dir_role, &meta, uid, &mut dir_findings);
            for f in dir_findings {
                out.push(Finding {
                    reason: format!(
                        "the directory holding it is {} (anyone who can write it can replace the file)",
                        f.reason
                    ),
                    path: path.to_path_buf(),
                    ..f
                });
            }
        }
    }
    out
}

fn judge(path: &Path, role: Role, meta: &std::fs::Metadata, uid: u32, out: &mut Vec<Finding>) {
    let mode = meta.mode();
    let owner = meta.uid();
    if mode & 0o002 != 0 {
        out.push(Finding {
            path: path.to_path_buf(),
            role,
            severity: Severity::Refuse,
            reason: format!(
                "writable by every user (mode {:o}); run chmod o-w",
                mode & 0o7777
            ),
        });
    } else if owner != uid && owner != 0 && mode & 0o200 != 0 {
        out.push(Finding {
            path: path.to_path_buf(),
            role,
            severity: Severity::Refuse,
            reason: format!(
                "owned and writable by another user (uid {owner}, the daemon runs as uid {uid})"
            ),
        });
    } else if mode & 0o020 != 0 {
        out.push(Finding {
            path: path.to_path_buf(),
            role,
            severity: Severity::Warning,
            reason: format!("group-writable (mode {:o})", mode & 0o7777),
        });
    }
}

/// Every finding for the daemon's paths.
pub(crate) fn check_daemon_paths(
    config: &Path,
    engine_file: Option<&Path>,
    database: &Path,
    uid: u32,
) -> Vec<Finding> {
    let mut out = check_path(config, Role::Config, uid);
    if let Some(e) = engine_file {
        out.extend(check_path(e, Role::EngineFile, uid));
    }
    out.extend(check_path(database, Role::Database, uid));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn chmod(p: &Path, mode: u32) {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
    }

    #[test]
    fn world_writable_config_is_refused_with_path_and_reason() {
        let dir = tempfile::tempdir().unwrap();
        chmod(dir.path(), 0o755);
        let cfg = dir.path().join("gtwatch.toml");
        std::fs::write(&cfg, "x").unwrap();
        chmod(&cfg, 0o666);
        let f = check_path(&cfg, Role::Config, current_uid());
        assert_eq!(f.len(), 1, "{f:?}");
        assert_eq!(f[0].severity, Severity::Refuse);
        let msg = f[0].to_string();
        assert!(
            msg.contains("gtwatch.toml") && msg.contains("writable by every user"),
            "{msg}"
        );
        chmod(&cfg, 0o644);
        assert!(check_path(&cfg, Role::Config, current_uid()).is_empty());
    }

    #[test]
    fn world_writable_directory_is_refused_unless_sticky() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("gtwatch.db");
        chmod(dir.path(), 0o777);
        let f = check_path(&db, Role::Database, current_uid());
        assert_eq!(f.len(), 1, "{f:?}");
        assert_eq!(f[0].role, Role::DatabaseDirectory);
        assert!(
            f[0].reason.contains("directory holding it"),
            "{}",
            f[0].reason
        );
        chmod(dir.path(), 0o1777);
        assert!(check_path(&db, Role::Database, current_uid()).is_empty());
        chmod(dir.path(), 0o700);
    }

    #[test]
    fn group_writable_is_a_warning_and_another_owner_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        chmod(dir.path(), 0o755);
        let p = dir.path().join("engine.toml");
        std::fs::write(&p, "x").unwrap();
        chmod(&p, 0o664);
        let f = check_path(&p, Role::EngineFile, current_uid());
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].severity, Severity::Warning);
        // Seen from a uid that owns neither the file nor is root, the file's owner is "another
        // user": the daemon must refuse (unless that owner is root).
        let me = current_uid();
        let other = if me == 4242 { 4243 } else { 4242 };
        chmod(&p, 0o644);
        let f = check_path(&p, Role::EngineFile, other);
        if me == 0 {
            // root owns the file: trusted from any uid.
            assert!(f.iter().all(|x| x.severity != Severity::Refuse), "{f:?}");
        } else {
            assert!(f.iter().any(|x| x.severity == Severity::Refuse), "{f:?}");
        }
    }

    #[test]
    fn missing_paths_are_not_findings() {
        let dir = tempfile::tempdir().unwrap();
        chmod(dir.path(), 0o755);
        let f = check_daemon_paths(
            &dir.path().join("none.toml"),
            None,
            &dir.path().join("none.db"),
            current_uid(),
        );
        assert!(f.is_empty(), "{f:?}");
    }
}
