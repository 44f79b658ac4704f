//! The layering rules of `docs/architecture.md`, checked on the source: which of the
//! library's top-level modules may name which (`crate::…` paths, comments excluded), that
//! estimators are leaves (no module names an estimator's but the registry, and no estimator
//! names another), and that no other crate downcasts an estimator. A broken rule names the
//! file, the line and the rule.

use std::collections::BTreeSet;

use std::path::{Path, PathBuf};

/// The library's layers, lowest first, and the top-level modules in each. A module may name
/// modules of its own layer and of the layers below (foundations among themselves freely).
const LAYERS: &[(&str, &[&str])] = &[
    (
        "foundations",
        &[
            "math", "color", "sampling", "texture", "geometry", "camera", "material", "light", "scene", "film",
            "imageio", "boundary",
        ],
    ),
    ("kit", &["paths"]),
    ("contract", &["integrator"]),
    ("analysis", &["guided"]),
    ("estimators", &["estimators"]),
    ("application", &["job", "shard", "compare", "eval", "checkpoint", "debug"]),
];

/// The estimator modules (leaves) and the only files that may name them.
const LEAVES: &[&str] = &["pt", "lt", "bpt", "ibpt", "skelpt", "portalpt", "skelbpt", "icbpt"];
const LEAF_DOORS: &[&str] = &["estimators/mod.rs", "estimators/registry.rs", "estimators/resampling/mod.rs"];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The file's code without comments (`//` to the end of the line, `/* … */`), line by line;
/// string literals are blanked so that a `//` or a path inside one counts for nothing.
fn code_lines(path: &Path) -> Vec<(usize, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = Vec::new();
    let (mut block, mut string) = (0usize, false);
    for (i, line) in text.lines().enumerate() {
        let mut code = String::new();
        let chars: Vec<char> = line.chars().collect();
        let mut k = 0;
        while k < chars.len() {
            let (c, next) = (chars[k], chars.get(k + 1).copied());
            if block > 0 {
                if c == '*' && next == Some('/') {
                    block -= 1;
                    k += 1;
                } else if c == '/' && next == Some('*') {
                    block += 1;
                    k += 1;
                }
            } else if string {
                if c == '\\' {
                    k += 1;
                } else if c == '"' {
                    string = false;
                    code.push('"');
                }
            } else if c == '/' && next == Some('/') {
                break;
            } else if c == '/' && next == Some('*') {
                block += 1;
                k += 1;
            } else if c == '"' && !code.ends_with('\'') {
                string = true;
                code.push('"');
            } else {
                code.push(c);
            }
            k += 1;
        }
        out.push((i + 1, code));
    }
    out
}

/// The module path of a source file relative to `src` (`paths/walk.rs` → paths, walk;
/// `estimators/mod.rs` → estimators).
fn module_path(rel: &str) -> Vec<String> {
    let mut parts: Vec<String> = rel.trim_end_matches(".rs").split('/').map(str::to_string).collect();
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    parts
}

fn identifier(text: &str) -> &str {
    let end = text.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(text.len());
    &text[..end]
}

/// The path `text` starts with, segment by segment, with a brace group (`{a::b, c}`)
/// expanded into one path per item: `x::{y, z::w}` → [x, y], [x, z, w].
fn expand(text: &str) -> Vec<Vec<String>> {
    let text = text.trim_start();
    if let Some(group) = text.strip_prefix('{') {
        let (mut depth, mut item_start, mut out) = (0i32, 0, Vec::new());
        for (i, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    out.extend(expand(&group[item_start..i]));
                    return out;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    out.extend(expand(&group[item_start..i]));
                    item_start = i + 1;
                }
                _ => {}
            }
        }
        out.extend(expand(&group[item_start..]));
        return out;
    }
    let head = identifier(text);
    if head.is_empty() {
        return vec![Vec::new()];
    }
    let rest = &text[head.len()..];
    match rest.trim_start().strip_prefix("::") {
        Some(tail) => expand(tail)
            .into_iter()
            .map(|mut p| {
                p.insert(0, head.to_string());
                p
            })
            .collect(),
        None => vec![vec![head.to_string()]],
    }
}

/// Every absolute module path the code names from module `own`: `crate::…`, and
/// `super::…`/`self::…` chains resolved from `own`, with use-groups expanded (a statement
/// spanning lines is joined first, and reported at its first line).
fn named_paths(lines: &[(usize, String)], own: &[String]) -> Vec<(usize, Vec<String>)> {
    // Joins each `use … ;` onto its first line.
    let mut joined: Vec<(usize, String)> = Vec::new();
    let mut open: Option<(usize, String)> = None;
    for (n, line) in lines {
        if let Some((at, text)) = open.as_mut() {
            text.push(' ');
            text.push_str(line);
            if line.contains(';') {
                joined.push((*at, std::mem::take(text)));
                open = None;
            }
            continue;
        }
        if (line.trim_start().starts_with("use ") || line.contains(" use ")) && !line.contains(';') {
            open = Some((*n, line.clone()));
            continue;
        }
        joined.push((*n, line.clone()));
    }
    let mut out = Vec::new();
    for (n, line) in joined {
        for (i, _) in
            line.match_indices("crate::").chain(line.match_indices("super::")).chain(line.match_indices("self::"))
        {
            if line[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            for path in expand(&line[i..]) {
                let mut absolute: Vec<String> = match path.first().map(String::as_str) {
                    Some("crate") => Vec::new(),
                    Some("self") => own.to_vec(),
                    Some("super") => own.to_vec(),
                    _ => continue,
                };
                let mut segments = path.iter().skip(1).peekable();
                if path[0] == "super" {
                    absolute.pop();
                    while segments.peek().is_some_and(|s| *s == "super") {
                        absolute.pop();
                        segments.next();
                    }
                }
                absolute.extend(segments.cloned());
                if !absolute.is_empty() {
                    out.push((n, absolute));
                }
            }
        }
    }
    out
}

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, mods)| mods.contains(&module))
}

/// Top-level module of a source file, relative to `src`.
fn module_of(rel: &str) -> &str {
    rel.split(['/', '.']).next().unwrap()
}

/// Every rule broken in the library's sources (empty when the layout is sound).
fn broken_rules(root: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(root, &mut files);
    let mut broken = Vec::new();
    for path in &files {
        let rel = path.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
        if rel == "lib.rs" || rel == "main.rs" {
            continue;
        }
        let own = module_of(&rel);
        let Some(own_layer) = layer_of(own) else {
            broken.push(format!("{rel}: top-level module '{own}' is in no layer of docs/architecture.md"));
            continue;
        };
        let stem = Path::new(&rel).file_stem().unwrap().to_string_lossy().to_string();
        let is_leaf = own == "estimators" && LEAVES.contains(&stem.as_str());
        let lines = code_lines(path);
        for (n, named) in named_paths(&lines, &module_path(&rel)) {
            let used = named[0].as_str();
            match layer_of(used) {
                Some(l) if l > own_layer && !(own_layer == 0 && l == 0) => broken.push(format!(
                    "{rel}:{n}: {} ({own}) names {used} ({}), a layer above it",
                    LAYERS[own_layer].0, LAYERS[l].0
                )),
                _ => {}
            }
            // Estimators are leaves: only their doors name them, and no leaf names another.
            let leaf =
                (used == "estimators").then(|| named.iter().skip(1).find(|s| LEAVES.contains(&s.as_str()))).flatten();
            if let Some(leaf) = leaf.filter(|l| **l != stem && !LEAF_DOORS.contains(&rel.as_str())) {
                let who = if is_leaf { "an estimator" } else { "a module" };
                broken.push(format!("{rel}:{n}: {who} names the estimator '{leaf}' (only the registry may)"));
            }
        }
        // A door other than the registry declares its leaves privately and hands them to the
        // registry alone (`pub(super) use`): a public `mod` or re-export would open a leaf.
        if LEAF_DOORS.contains(&rel.as_str()) && rel != "estimators/registry.rs" {
            for (n, line) in &lines {
                let t = line.trim_start();
                let public = (t.starts_with("pub use") || t.starts_with("pub(crate) use") || t.starts_with("pub mod"))
                    || t.starts_with("pub(crate) mod");
                let names_leaf = LEAVES.iter().any(|l| {
                    t.match_indices(l).any(|(i, _)| {
                        let before = t[..i].chars().last().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
                        let after = t[i + l.len()..].chars().next().is_none_or(|c| !(c.is_alphanumeric() || c == '_'));
                        before && after
                    })
                });
                if public && names_leaf {
                    broken.push(format!("{rel}:{n}: a door opens an estimator to the crate ({})", t.trim()));
                }
            }
        }
    }
    broken
}

#[test]
fn the_library_keeps_its_layers() {
    let broken = broken_rules(&src());
    assert!(broken.is_empty(), "docs/architecture.md's rules broken:\n{}", broken.join("\n"));
}

/// The check fails where it should: a copy of the sources with the kit naming an estimator,
/// the analysis naming the estimators' folder, and one estimator naming another.
#[test]
fn the_layer_check_sees_a_broken_rule() {
    let copy = Path::new(env!("CARGO_TARGET_TMPDIR")).join("architecture-broken");
    let _ = std::fs::remove_dir_all(&copy);
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    for f in &files {
        let to = copy.join(f.strip_prefix(src()).unwrap());
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(f, &to).unwrap();
    }
    let append = |rel: &str, line: &str| {
        let p = copy.join(rel);
        let text = std::fs::read_to_string(&p).unwrap() + line;
        std::fs::write(p, text).unwrap();
    };
    append("paths/walk.rs", "\nuse crate::estimators::registry;\n");
    append("guided/analysis.rs", "\nfn f() { crate::estimators::by_name(\"pt\"); }\n");
    append("estimators/skelpt.rs", "\nuse super::pt::PathTracer;\n");
    // The forms a line-by-line reading would miss: a use-group over lines, `super::super`,
    // a grouped leaf, a door's public re-export; and a path inside a string names nothing.
    append("paths/mis.rs", "\nuse crate::{\n    math::Vec3,\n    guided::SkeletonGuide,\n};\n");
    append("paths/bidir.rs", "\nfn g() { super::super::estimators::names(); }\n");
    append("estimators/lt.rs", "\nuse super::{registry, ibpt::InstantBpt};\n");
    append("estimators/mod.rs", "\npub use pt::PathTracer;\n");
    append("paths/vertex.rs", "\nconst URL: &str = \"http://x crate::estimators::pt\"; /* crate::guided */\n");
    let broken = broken_rules(&copy);
    let seen = |what: &str| broken.iter().any(|b| b.contains(what));
    assert!(seen("paths/walk.rs") && seen("a layer above"), "{broken:?}");
    assert!(seen("guided/analysis.rs"), "{broken:?}");
    assert!(seen("estimators/skelpt.rs") && seen("names the estimator 'pt'"), "{broken:?}");
    assert!(seen("paths/mis.rs") && seen("names guided"), "{broken:?}");
    assert!(seen("paths/bidir.rs"), "{broken:?}");
    assert!(seen("estimators/lt.rs") && seen("names the estimator 'ibpt'"), "{broken:?}");
    assert!(seen("estimators/mod.rs") && seen("opens an estimator"), "{broken:?}");
    assert!(!seen("paths/vertex.rs"), "{broken:?}");
    assert_eq!(broken.len(), 7, "{broken:?}");
}

/// The other crates reach estimators by name: none downcasts one, none names a leaf.
#[test]
fn no_crate_downcasts_an_estimator() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let mut offenders = BTreeSet::new();
    for krate in ["skelight-cli", "skelight-py", "skelight-gpu"] {
        let mut files = Vec::new();
        rust_files(&crates.join(krate).join("src"), &mut files);
        for f in files {
            for (n, line) in code_lines(&f) {
                if line.contains("as_any") || line.contains("downcast_ref::<") {
                    offenders.insert(format!("{}:{n}: {}", f.display(), line.trim()));
                }
            }
        }
    }
    assert!(offenders.is_empty(), "downcasts outside the library: {offenders:#?}");
}

/// The registry is the manual: the README's estimator table has a row for every estimator,
/// naming each of its parameters with its default, and no row for one that does not exist.
#[test]
fn the_readme_table_is_the_registry() {
    let readme = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md");
    let text = std::fs::read_to_string(&readme).unwrap();
    let rows: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("| estimator | what | parameters"))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .collect();
    let mut missing = Vec::new();
    for e in skelight::estimators::ESTIMATORS {
        let Some(row) = rows.iter().find(|r| r.starts_with(&format!("| `{}` |", e.name))) else {
            missing.push(format!("no row for {}", e.name));
            continue;
        };
        for p in e.params {
            if !row.contains(&format!("`{}`", p.name)) || !row.contains(&format!("({}", p.default)) {
                missing.push(format!("{}: parameter `{}` with its default ({}) missing", e.name, p.name, p.default));
            }
        }
    }
    let names = skelight::estimators::names();
    for r in &rows {
        let name = r.split('`').nth(1).unwrap_or("");
        if !names.contains(&name) {
            missing.push(format!("a row for '{name}', which the registry does not have"));
        }
    }
    assert!(missing.is_empty(), "README.md's estimator table and the registry differ:\n{}", missing.join("\n"));
}
