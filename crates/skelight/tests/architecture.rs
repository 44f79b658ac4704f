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
const LEAVES: &[&str] = &["pt", "lt", "bpt", "ibpt", "skelpt", "skelbpt", "icbpt"];
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

/// The file's lines without comments (`//` to the end of the line).
fn code_lines(path: &Path) -> Vec<(usize, String)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split("//").next().unwrap_or("").to_string()))
        .collect()
}

/// Identifiers that follow `prefix` in `line` (`crate::` → the top-level module named).
fn names_after<'a>(line: &'a str, prefix: &str) -> Vec<&'a str> {
    line.match_indices(prefix)
        .filter(|(i, _)| !line[..*i].ends_with(|c: char| c.is_alphanumeric() || c == '_'))
        .map(|(i, _)| {
            let rest = &line[i + prefix.len()..];
            let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(rest.len());
            &rest[..end]
        })
        .collect()
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
        for (n, line) in code_lines(path) {
            for used in names_after(&line, "crate::") {
                match layer_of(used) {
                    Some(l) if l > own_layer && !(own_layer == 0 && l == 0) => broken.push(format!(
                        "{rel}:{n}: {} ({own}) names {used} ({}), a layer above it",
                        LAYERS[own_layer].0, LAYERS[l].0
                    )),
                    _ => {}
                }
            }
            // Estimators are leaves: only their doors name them, and no leaf names another.
            if !LEAF_DOORS.contains(&rel.as_str()) {
                for prefix in ["estimators::", "resampling::", "super::"] {
                    for used in names_after(&line, prefix) {
                        let named_leaf = LEAVES.contains(&used) && used != stem;
                        let from_estimators = own == "estimators" || prefix == "estimators::";
                        if named_leaf && from_estimators {
                            let who = if is_leaf { "an estimator" } else { "a module" };
                            broken
                                .push(format!("{rel}:{n}: {who} names the estimator '{used}' (only the registry may)"));
                        }
                    }
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
    let broken = broken_rules(&copy);
    let seen = |what: &str| broken.iter().any(|b| b.contains(what));
    assert!(seen("paths/walk.rs") && seen("a layer above"), "{broken:?}");
    assert!(seen("guided/analysis.rs"), "{broken:?}");
    assert!(seen("estimators/skelpt.rs") && seen("names the estimator 'pt'"), "{broken:?}");
    assert_eq!(broken.len(), 3, "{broken:?}");
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
