//! The house, checked: every top-level module of `src/` (a room) sits on a floor, and non-test
//! code may refer only to rooms on its own floor or below (arrows only point down), never to a
//! room that refers back to it (no two rooms refer to each other).
//!
//! The floors are the table in README.md's "Architecture" section; [`FLOORS`] below is the same
//! table, and this test is what keeps the two and the code honest. It reads the sources itself
//! (no compiler help): comments and string literals are blanked, items under `#[cfg(test)]`
//! (and the files of `#[cfg(test)] mod …;` declarations, `tests.rs`, `*_tests.rs`) are skipped,
//! and every `crate::room` path (including `use crate::{a, b}` groups and `$crate::` in macros)
//! counts as a reference from the file's room to that room. `super::` paths are not followed
//! (they stay inside a room in this code base). `lib.rs` and `main.rs` are the roof: they
//! declare and start everything and are not checked.
//!
//! Must not build or run any of the crate: it reads text only, so it is fast and cannot be
//! fooled by a feature flag.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Room (top-level module of `src/`) → floor. Floor 0 is the ground: it refers to nothing above
/// it. Keep in step with README.md, section "Architecture".
const FLOORS: &[(&str, u8)] = &[
    // 0 — foundations: pure physics and maths, and the plain types and text formats every floor
    // shares. No I/O (the CSV/Modbus/SQL kind), no async, no database, no daemon.
    ("thermo", 0),
    ("maps", 0),
    ("health", 0),
    ("signals", 0),
    ("optim", 0),
    ("recording", 0),
    ("quality", 0),
    ("segment", 0),
    ("time", 0),
    ("config_problem", 0),
    ("metrics", 0),
    ("units", 0),
    // 1 — the engine model.
    ("engine", 1),
    // 2 — what is computed with the model: diagnosis, calibration, gap analysis, trends, wash
    // economics, and the SVG writer that draws their results.
    ("diagnosis", 2),
    ("calibrate", 2),
    ("gap", 2),
    ("trend", 2),
    ("wash", 2),
    ("chart", 2),
    // 3 — data: the store (the one owner of SQL), getting data in (replay, acquisition, the
    // bad-value gate), start-up detection, the read-side queries, file-permission checks and
    // the shutdown signal the tasks share, and the fleet sync of what the store holds to a
    // central PostgreSQL.
    ("store", 3),
    ("ingest", 3),
    ("acquire", 3),
    ("detect", 3),
    ("query", 3),
    ("permissions", 3),
    ("shutdown", 3),
    ("fleet", 3),
    // 4 — services built from the floors below: the diagnosis worker, wash advice, the report,
    // the daemon, the plant simulator, the demo, and the configuration file that assembles
    // every task's section.
    ("worker", 4),
    ("advice", 4),
    ("report", 4),
    ("daemon", 4),
    ("plantsim", 4),
    ("demo", 4),
    ("config", 4),
    // 5 — the benchmarks: each drives the floors below the way the product runs them and
    // measures it.
    ("bench", 5),
    // 6 — the command line.
    ("cli", 6),
];

/// One source file: its path relative to `src/` (with `/`) and its text.
struct Source {
    path: String,
    text: String,
}

/// A reference from one room to another, where it was written.
#[derive(Debug, Clone)]
struct Ref {
    from: String,
    to: String,
    path: String,
    line: usize,
}

/// The source with comments and the contents of string and char literals replaced by spaces,
/// byte for byte (newlines kept), so offsets and line numbers stay those of the file.
fn blank_comments_and_strings(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let blank = |out: &mut String, ch: char| {
        if ch == '\n' {
            out.push('\n');
        } else {
            out.extend(std::iter::repeat_n(' ', ch.len_utf8()));
        }
    };
    let is_ident = |ch: char| ch.is_alphanumeric() || ch == '_';
    let at = |k: usize| c.get(k).copied().unwrap_or('\0');
    let mut i = 0;
    while i < c.len() {
        if c[i] == '/' && at(i + 1) == '/' {
            while i < c.len() && c[i] != '\n' {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '/' && at(i + 1) == '*' {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && at(i + 1) == '*' {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if (c[i] == 'r' || (c[i] == 'b' && at(i + 1) == 'r'))
            && (i == 0 || !is_ident(c[i - 1]))
            && {
                let mut k = if c[i] == 'b' { i + 2 } else { i + 1 };
                while at(k) == '#' {
                    k += 1;
                }
                at(k) == '"'
            }
        {
            // Raw string: r"…", r#"…"#, br#"…"#.
            let start = if c[i] == 'b' { i + 2 } else { i + 1 };
            let mut k = start;
            while at(k) == '#' {
                k += 1;
            }
            let hashes = k - start;
            out.extend(&c[i..=k]);
            i = k + 1;
            while i < c.len() {
                if c[i] == '"' && (0..hashes).all(|h| at(i + 1 + h) == '#') {
                    out.extend(&c[i..=i + hashes]);
                    i += 1 + hashes;
                    break;
                }
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '"' {
            out.push('"');
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < c.len() {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
            if i < c.len() {
                out.push('"');
                i += 1;
            }
        } else if c[i] == '\'' && (at(i + 1) == '\\' || (at(i + 2) == '\'' && at(i + 1) != '\'')) {
            // A char literal ('a', '\n', '\'', '\u{1F600}'); a lifetime ('a) is left alone.
            out.push('\'');
            i += 1;
            if c[i] == '\\' {
                out.push_str("  ");
                i += 2;
            }
            while i < c.len() && c[i] != '\'' && c[i] != '\n' {
                blank(&mut out, c[i]);
                i += 1;
            }
            if i < c.len() && c[i] == '\'' {
                out.push('\'');
                i += 1;
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// Byte offset → 1-based line number.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset].bytes().filter(|&b| b == b'\n').count() + 1
}

/// Blanks every item under `#[cfg(test)]` in already-blanked code (attributes after it, then
/// the item up to its `;` or its closing brace). Returns the remaining code and the names (with
/// their `#[path]`, if any) of the `#[cfg(test)] mod name;` declarations, whose files are test
/// code too.
fn blank_test_items(original: &str, code: &str) -> (String, Vec<(String, Option<String>)>) {
    let mut out: Vec<u8> = code.as_bytes().to_vec();
    let mut test_mods = Vec::new();
    let mut search = 0;
    while let Some(found) = code[search..].find("#[cfg(test)]") {
        let start = search + found;
        let b = code.as_bytes();
        let mut i = start + "#[cfg(test)]".len();
        // Further attributes (e.g. `#[path = "…"]`), remembering a path.
        let mut path_attr = None;
        loop {
            while i < b.len() && b[i].is_ascii_whitespace() {
                i += 1;
            }
            if b.get(i) == Some(&b'#') && b.get(i + 1) == Some(&b'[') {
                let end = code[i..].find(']').map_or(b.len(), |e| i + e + 1);
                let attr = &code[i..end];
                if attr.contains("path") {
                    // The blanked text lost the string's contents: read it from the original.
                    let text = &original[i..end];
                    if let (Some(q1), Some(q2)) = (text.find('"'), text.rfind('"')) {
                        path_attr = text.get(q1 + 1..q2).map(str::to_string);
                    }
                }
                i = end;
            } else {
                break;
            }
        }
        // The item itself: up to `;` at depth 0, or the brace closing its first `{`.
        let item_start = i;
        let mut depth = 0i32;
        let mut opened = false;
        while i < b.len() {
            match b[i] {
                b'{' | b'(' | b'[' => {
                    if b[i] == b'{' && depth == 0 {
                        opened = true;
                    }
                    depth += 1;
                }
                b'}' | b')' | b']' => {
                    depth -= 1;
                    if depth == 0 && opened && b[i] == b'}' {
                        i += 1;
                        break;
                    }
                }
                b';' if depth == 0 => {
                    i += 1;
                    break;
                }
                _ => {}
            }
            i += 1;
        }
        let item = code[item_start..i].trim();
        let words: Vec<&str> = item
            .split(|ch: char| !(ch.is_alphanumeric() || ch == '_'))
            .filter(|w| !w.is_empty())
            .collect();
        if !opened {
            if let Some(k) = words.iter().position(|w| *w == "mod") {
                if let Some(name) = words.get(k + 1) {
                    test_mods.push((name.to_string(), path_attr.clone()));
                }
            }
        }
        for byte in &mut out[start..i] {
            if *byte != b'\n' {
                *byte = b' ';
            }
        }
        search = i.max(start + 1);
    }
    (String::from_utf8_lossy(&out).into_owned(), test_mods)
}

/// The rooms a piece of blanked code refers to through `crate::` paths, with byte offsets.
fn crate_refs(code: &str) -> Vec<(String, usize)> {
    let is_ident = |ch: u8| ch.is_ascii_alphanumeric() || ch == b'_';
    let b = code.as_bytes();
    let mut refs = Vec::new();
    let mut search = 0;
    while let Some(found) = code[search..].find("crate::") {
        let at = search + found;
        search = at + "crate::".len();
        if at > 0 && is_ident(b[at - 1]) {
            continue; // `my_crate::…`, not ours.
        }
        let mut i = search;
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if b.get(i) == Some(&b'{') {
            // `crate::{a::X, b, c::{d, e}}`: the first segment of each top-level entry.
            let mut depth = 0;
            let mut expect_name = true;
            i += 1;
            while i < b.len() {
                match b[i] {
                    b'{' => depth += 1,
                    b'}' if depth == 0 => break,
                    b'}' => depth -= 1,
                    b',' if depth == 0 => expect_name = true,
                    ch if expect_name && is_ident(ch) => {
                        let s = i;
                        while i < b.len() && is_ident(b[i]) {
                            i += 1;
                        }
                        refs.push((code[s..i].to_string(), s));
                        expect_name = false;
                        continue;
                    }
                    _ => {}
                }
                i += 1;
            }
        } else {
            let s = i;
            while i < b.len() && is_ident(b[i]) {
                i += 1;
            }
            if i > s {
                refs.push((code[s..i].to_string(), s));
            }
        }
    }
    refs
}

/// The room of a file: its first path component, without `.rs`.
fn room_of(path: &str) -> String {
    let first = path.split('/').next().unwrap_or(path);
    first.trim_end_matches(".rs").to_string()
}

/// The files a `#[cfg(test)] mod name;` declared in `decl_path` lives in (a file, or every file
/// of a folder).
fn test_module_files(decl_path: &str, name: &str, path_attr: Option<&str>) -> Vec<String> {
    let (dir, file) = match decl_path.rfind('/') {
        Some(k) => (&decl_path[..k], &decl_path[k + 1..]),
        None => ("", decl_path),
    };
    let join = |a: &str, b: &str| {
        if a.is_empty() {
            b.to_string()
        } else {
            format!("{a}/{b}")
        }
    };
    if let Some(p) = path_attr {
        return vec![join(dir, p)];
    }
    let base = if file == "mod.rs" || file == "lib.rs" || file == "main.rs" {
        dir.to_string()
    } else {
        join(dir, file.trim_end_matches(".rs"))
    };
    vec![
        join(&base, &format!("{name}.rs")),
        join(&base, &format!("{name}/")),
    ]
}

/// Checks the sources against the floors; returns one message per violation (empty = the
/// house stands).
fn check(floors: &[(&str, u8)], declared: &[String], files: &[Source]) -> Vec<String> {
    let floor: BTreeMap<&str, u8> = floors.iter().copied().collect();
    let mut problems = Vec::new();
    for room in declared {
        if !floor.contains_key(room.as_str()) {
            problems.push(format!(
                "src/lib.rs: module `{room}` is on no floor: add it to FLOORS in \
                 tests/architecture.rs and to README.md's Architecture table"
            ));
        }
    }
    for (room, _) in floors {
        if !declared.iter().any(|d| d == room) {
            problems.push(format!(
                "FLOORS names `{room}`, which src/lib.rs does not declare"
            ));
        }
    }
    // First pass: blank test code, note the files of test-only modules.
    let mut code_of: Vec<(&Source, String)> = Vec::new();
    let mut test_files: Vec<String> = Vec::new();
    for f in files {
        let blanked = blank_comments_and_strings(&f.text);
        let (code, mods) = blank_test_items(&f.text, &blanked);
        for (name, path_attr) in mods {
            test_files.extend(test_module_files(&f.path, &name, path_attr.as_deref()));
        }
        code_of.push((f, code));
    }
    let is_test_file = |path: &str| {
        let name = path.rsplit('/').next().unwrap_or(path);
        name == "tests.rs"
            || name.ends_with("_tests.rs")
            || test_files
                .iter()
                .any(|t| t == path || (t.ends_with('/') && path.starts_with(t.as_str())))
    };
    // Second pass: references.
    let mut refs: Vec<Ref> = Vec::new();
    for (f, code) in &code_of {
        if f.path == "lib.rs" || f.path == "main.rs" || is_test_file(&f.path) {
            continue;
        }
        let from = room_of(&f.path);
        for (to, offset) in crate_refs(code) {
            if to != from && floor.contains_key(to.as_str()) {
                refs.push(Ref {
                    from: from.clone(),
                    to,
                    path: f.path.clone(),
                    line: line_of(code, offset),
                });
            }
        }
    }
    for r in &refs {
        let (Some(&lo), Some(&hi)) = (floor.get(r.from.as_str()), floor.get(r.to.as_str())) else {
            continue;
        };
        if hi > lo {
            problems.push(format!(
                "src/{}:{}: `{}` (floor {lo}) refers to `{}` (floor {hi}), a floor above it",
                r.path, r.line, r.from, r.to
            ));
        }
    }
    let mut first: BTreeMap<(&str, &str), &Ref> = BTreeMap::new();
    for r in &refs {
        first.entry((r.from.as_str(), r.to.as_str())).or_insert(r);
    }
    let mut seen = BTreeSet::new();
    for (&(a, b), r) in &first {
        if let Some(back) = first.get(&(b, a)) {
            if seen.insert((a.min(b), a.max(b))) {
                problems.push(format!(
                    "src/{}:{}: `{a}` refers to `{b}`, and src/{}:{}: `{b}` refers back to `{a}`: \
                     two rooms refer to each other (move what both need down a floor)",
                    r.path, r.line, back.path, back.line
                ));
            }
        }
    }
    problems
}

/// Every `.rs` file under `dir`, with paths relative to `root`.
fn read_sources(root: &Path, dir: &Path, out: &mut Vec<Source>) -> std::io::Result<()> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    entries.sort();
    for p in entries {
        if p.is_dir() {
            read_sources(root, &p, out)?;
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p.strip_prefix(root).unwrap_or(&p);
            let path = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join("/");
            let text = std::fs::read_to_string(&p)?;
            out.push(Source { path, text });
        }
    }
    Ok(())
}

/// The top-level modules `src/lib.rs` declares.
fn declared_rooms(lib: &str) -> Vec<String> {
    lib.lines()
        .filter_map(|l| {
            let l = l.trim();
            let rest = l
                .strip_prefix("pub mod ")
                .or_else(|| l.strip_prefix("pub(crate) mod "))
                .or_else(|| l.strip_prefix("mod "))?;
            Some(rest.trim_end_matches(';').trim().to_string())
        })
        .collect()
}

#[test]
fn arrows_only_point_down() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_sources(&src, &src, &mut files).expect("reading src/");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("src/lib.rs");
    let problems = check(FLOORS, &declared_rooms(&lib), &files);
    assert!(
        problems.is_empty(),
        "{} architecture violation(s):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

/// With `autotests = false` (Cargo.toml), a test file that `tests/integration.rs` does not
/// declare is never built nor run, silently: every `tests/<name>.rs` and `tests/<name>/mod.rs`
/// must be one of its modules.
#[test]
fn every_test_file_is_a_module_of_the_one_test_binary() {
    let tests = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let root = std::fs::read_to_string(tests.join("integration.rs")).expect("tests/integration.rs");
    let declared: Vec<&str> = root
        .lines()
        .filter_map(|l| l.strip_prefix("mod ")?.strip_suffix(';'))
        .collect();
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(&tests).expect("tests/") {
        let path = entry.expect("entry").path();
        let name = if path.is_dir() && path.join("mod.rs").is_file() {
            path.file_name().and_then(|n| n.to_str()).map(str::to_owned)
        } else if path.extension().is_some_and(|e| e == "rs") {
            path.file_stem().and_then(|n| n.to_str()).map(str::to_owned)
        } else {
            None
        };
        if let Some(name) = name.filter(|n| n != "integration") {
            if !declared.contains(&name.as_str()) {
                missing.push(name);
            }
        }
    }
    missing.sort();
    assert!(
        missing.is_empty(),
        "not declared in tests/integration.rs, so never run: {missing:?}"
    );
}

#[test]
fn readme_table_matches_floors() {
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md"))
        .expect("README.md");
    let section = readme
        .split("\n## Architecture")
        .nth(1)
        .expect("README.md has an '## Architecture' section");
    let section = section.split("\n## ").next().unwrap_or(section);
    // Table rows: `| floor | rooms … |`, rooms written as `name`.
    let mut table: BTreeMap<String, u8> = BTreeMap::new();
    for line in section.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let Some(n) = cells.get(1).and_then(|c| c.parse::<u8>().ok()) else {
            continue;
        };
        let rooms = cells.get(2).copied().unwrap_or("");
        for (k, part) in rooms.split('`').enumerate() {
            if k % 2 == 1 {
                table.insert(part.trim_end_matches('/').to_string(), n);
            }
        }
    }
    let want: BTreeMap<String, u8> = FLOORS.iter().map(|(r, f)| (r.to_string(), *f)).collect();
    assert_eq!(
        table, want,
        "README.md's Architecture table differs from FLOORS"
    );
}

/// The checker itself, on fixtures written as strings: it must be able to fail.
mod checker {
    use super::*;

    fn src(path: &str, text: &str) -> Source {
        Source {
            path: path.to_string(),
            text: text.to_string(),
        }
    }

    const HOUSE: &[(&str, u8)] = &[("low", 0), ("mid", 1), ("peer", 1), ("top", 2)];

    fn rooms() -> Vec<String> {
        HOUSE.iter().map(|(r, _)| r.to_string()).collect()
    }

    #[test]
    fn flags_an_upward_use_with_file_and_line() {
        let files = [
            src("low.rs", "//! Ground.\n\nuse crate::top::Thing;\n"),
            src("top/mod.rs", "use crate::mid::X;\n"),
        ];
        let problems = check(HOUSE, &rooms(), &files);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(
            problems[0].starts_with("src/low.rs:3: `low` (floor 0) refers to `top` (floor 2)"),
            "{problems:?}"
        );
    }

    #[test]
    fn flags_paths_and_groups_not_only_use_lines() {
        let files = [
            src("mid/a.rs", "fn f() { let _ = crate::top::g(); }\n"),
            src("low.rs", "use crate::{mid::Y,\n    top::{Z, W}};\n"),
        ];
        let problems = check(HOUSE, &rooms(), &files);
        let joined = problems.join("\n");
        assert!(joined.contains("src/mid/a.rs:1: `mid`"), "{joined}");
        assert!(
            joined.contains("src/low.rs:1: `low` (floor 0) refers to `mid`"),
            "{joined}"
        );
        assert!(
            joined.contains("src/low.rs:2: `low` (floor 0) refers to `top`"),
            "{joined}"
        );
    }

    #[test]
    fn flags_two_rooms_referring_to_each_other() {
        let files = [
            src("mid.rs", "use crate::peer::A;\n"),
            src("peer/mod.rs", "\nuse crate::mid::B;\n"),
        ];
        let problems = check(HOUSE, &rooms(), &files);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].contains("src/mid.rs:1"), "{problems:?}");
        assert!(problems[0].contains("src/peer/mod.rs:2"), "{problems:?}");
    }

    #[test]
    fn ignores_tests_comments_strings_and_downward_references() {
        let files = [
            src(
                "low.rs",
                "//! See [`crate::top`].\n\
                 use crate::low::inner;\n\
                 const S: &str = \"crate::top::x\";\n\
                 const R: &str = r#\"crate::top\"#;\n\
                 fn f<'a>(x: &'a str) -> char { let _ = x; '{' }\n\
                 #[cfg(test)]\n\
                 use crate::top::Helper;\n\
                 #[cfg(test)]\n\
                 mod tests {\n    use crate::top::T;\n    fn g() { let _ = '}'; }\n}\n\
                 #[cfg(test)]\n\
                 #[path = \"low_checks.rs\"]\n\
                 mod checks;\n\
                 /* crate::top in a /* nested */ comment */\n",
            ),
            src("low_checks.rs", "use crate::top::U;\n"),
            src("low/tests.rs", "use crate::top::V;\n"),
            src("top/mod.rs", "use crate::mid::M;\nuse crate::low::L;\n"),
            src("lib.rs", "pub mod low;\nuse crate::top::Root;\n"),
        ];
        let problems = check(HOUSE, &rooms(), &files);
        assert!(problems.is_empty(), "{problems:?}");
    }

    #[test]
    fn every_declared_module_needs_a_floor() {
        let mut declared = rooms();
        declared.push("attic".to_string());
        let problems = check(HOUSE, &declared, &[]);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(
            problems[0].contains("`attic` is on no floor"),
            "{problems:?}"
        );
    }

    #[test]
    fn the_real_tree_would_fail_on_an_upward_use() {
        // The same check over today's sources plus one deliberately upward `use` fails.
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut files = Vec::new();
        read_sources(&root, &root, &mut files).expect("reading src/");
        let lib = std::fs::read_to_string(root.join("lib.rs")).expect("src/lib.rs");
        let f = files
            .iter_mut()
            .find(|f| f.path == "thermo/mod.rs")
            .expect("src/thermo/mod.rs");
        f.text = format!("use crate::cli::main;\n{}", f.text);
        let problems = check(FLOORS, &declared_rooms(&lib), &files);
        assert!(
            problems
                .iter()
                .any(|p| p.starts_with("src/thermo/mod.rs:1: `thermo` (floor 0) refers to `cli`")),
            "{problems:?}"
        );
    }
}
