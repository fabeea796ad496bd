//! The crate boundaries ARCHITECTURE.md states, checked from `cargo metadata` and the sources.
//!
//! * robot software (`robots/*`) never depends on the simulator (`sim/*`);
//! * the engine depends on no robot crate but `hetsim-msgs`, and its sources name no robot
//!   model;
//! * the engine is the loop and the radio: its modules are the loop's, and it depends on no
//!   file-format crate (recordings and datasets are `hetsim-io`'s);
//! * `hetsim-msgs` depends on nothing of ours;
//! * each heavy dependency lives in one crate (rapier in physics, wgpu in render, clap and
//!   indicatif and anyhow in the binary);
//! * one camera geometry type: only `hetsim-msgs` defines pinhole parameters, and the crate
//!   that builds robot stacks reaches no renderer through its dependencies;
//! * no code compares a robot's model to a name, and evaluation does not depend on
//!   `hetsim-stacks`;
//! * no library function returns a `String` error;
//! * no crate's top-level modules form a cycle through `crate::` paths;
//! * ARCHITECTURE.md's list of each crate's dependencies is the one `cargo metadata` gives.
//!
//! There is no cap on a file's length: a file holds one thing and a function does one step,
//! whatever their size.

use hetsim_tests::repo;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Our packages: name -> (folder relative to the repository, normal dependencies by name).
fn packages() -> BTreeMap<String, (String, Vec<String>)> {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(repo())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let root = repo().canonicalize().unwrap();
    let mut found = BTreeMap::new();
    for p in meta["packages"].as_array().unwrap() {
        let manifest = Path::new(p["manifest_path"].as_str().unwrap())
            .canonicalize()
            .unwrap();
        let rel = manifest
            .parent()
            .unwrap()
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .to_string();
        let deps = p["dependencies"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|d| d["kind"].is_null())
            .map(|d| d["name"].as_str().unwrap().to_string())
            .collect();
        found.insert(p["name"].as_str().unwrap().to_string(), (rel, deps));
    }
    assert!(found.len() >= 10, "{found:?}");
    found
}

#[test]
fn robots_crates_never_depend_on_sim_crates() {
    let all = packages();
    let robots: Vec<&String> = all
        .iter()
        .filter(|(_, (f, _))| f.starts_with("robots/"))
        .map(|(n, _)| n)
        .collect();
    assert!(robots.len() >= 5, "{all:?}");
    for name in robots {
        for dep in &all[name].1 {
            if let Some((f, _)) = all.get(dep) {
                assert!(
                    !f.starts_with("sim/"),
                    "{name} ({}) depends on {dep} ({f})",
                    all[name].0
                );
            }
        }
    }
}

#[test]
fn the_engine_knows_no_robot_software_but_the_messages() {
    let all = packages();
    let (_, deps) = &all["hetsim-engine"];
    for dep in deps {
        if let Some((f, _)) = all.get(dep) {
            assert!(
                !f.starts_with("robots/") || dep == "hetsim-msgs",
                "hetsim-engine depends on robot crate {dep} ({f}); robot software is wired in hetsim-stacks"
            );
        }
    }
    assert!(deps.iter().any(|d| d == "hetsim-msgs"));
    // The boundary crate depends on nothing of ours.
    let (_, msgs) = &all["hetsim-msgs"];
    assert!(
        msgs.iter().all(|d| !all.contains_key(d)),
        "hetsim-msgs depends on {msgs:?}"
    );
    // Evaluation reads the engine's outputs; the engine never reads evaluation.
    assert!(!deps
        .iter()
        .any(|d| d == "hetsim-eval" || d == "hetsim-stacks"));
}

#[test]
fn the_engine_names_no_robot_model() {
    // What a robot is comes from its robot file, never from its model's name.
    let models: Vec<String> = std::fs::read_dir(repo().join("robots/models"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().to_string())
        .collect();
    assert!(models.len() >= 4, "{models:?}");
    for f in sources(&repo().join("sim/engine/src")) {
        if f.components().any(|c| c.as_os_str() == "tests") {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        for m in &models {
            assert!(
                !text.contains(&format!("\"{m}\"")),
                "{} names the robot model {m:?}",
                f.display()
            );
        }
    }
}

#[test]
fn no_code_compares_robot_models_by_name_and_evaluation_calls_no_stacks() {
    // Roles (a coverage parent, a child) come from what robot files declare (a laser, a hat),
    // so a researcher's robot under another name plays them too.
    for dir in ["sim", "robots"] {
        for f in sources(&repo().join(dir)) {
            let text = std::fs::read_to_string(&f).unwrap();
            let code = non_test_code(&text);
            for pattern in ["model == \"", "model != \""] {
                assert!(
                    !code.contains(pattern),
                    "{} compares a robot model to a name ({pattern}...)",
                    f.display()
                );
            }
        }
    }
    // Evaluation judges a run from its outputs and the files; it never asks the crate that
    // builds the robot software what that software was given.
    let all = packages();
    assert!(!all["hetsim-eval"].1.iter().any(|d| d == "hetsim-stacks"));
}

#[test]
fn robot_crates_own_their_tables_and_the_loader_and_stacks_keep_no_copy() {
    // The fields of a robot file's [slam] and [pilot] and a scenario's [coverage] are
    // declared once, in the crate whose software they set; the loader (hetsim-scene) and
    // the crate that builds the stacks declare none of them again.
    let mut fields = BTreeSet::new();
    let names = |v: serde_json::Value| -> Vec<String> {
        v.as_object().expect("a table").keys().cloned().collect()
    };
    fields.extend(names(
        serde_json::to_value(hetsim_slam::stack::SlamParams::ground()).unwrap(),
    ));
    fields.extend(names(
        serde_json::to_value(hetsim_coverage::CoverageTable::default()).unwrap(),
    ));
    let pilot: hetsim_scene::PilotTable =
        serde_json::from_str(r#"{"cruise_mps": 1.0, "arrive_m": 0.5}"#).unwrap();
    fields.extend(names(serde_json::to_value(pilot).unwrap()));
    assert!(fields.len() >= 20 && fields.contains("sigma_px") && fields.contains("reaim_m"));
    for dir in ["sim/scene", "sim/stacks"] {
        for f in sources(&repo().join(dir)) {
            let text = std::fs::read_to_string(&f).unwrap();
            let code = non_test_code(&text);
            for field in &fields {
                assert!(
                    !code.contains(&format!("pub {field}:")),
                    "{} declares `{field}`, a field of a table a robot crate owns",
                    f.display()
                );
            }
        }
    }
}

#[test]
fn no_library_function_returns_a_string_error() {
    // Errors are typed (thiserror enums with their fields), so a caller can match on them;
    // only the binary (anyhow) turns them into text.
    for dir in ["sim", "robots"] {
        for f in sources(&repo().join(dir)) {
            if f.starts_with(repo().join("sim/cli")) {
                continue;
            }
            let text = std::fs::read_to_string(&f).unwrap();
            let code = non_test_code(&text);
            let flat: String = code.split_whitespace().collect::<Vec<_>>().join(" ");
            for (i, _) in flat.match_indices("Result<") {
                assert_ne!(
                    error_type(&flat[i + "Result<".len()..]).as_deref(),
                    Some("String"),
                    "{} returns a String error: {}",
                    f.display(),
                    flat[i..].chars().take(100).collect::<String>()
                );
            }
        }
    }
}

/// A source file without its inline test module (`#[cfg(test)] mod tests { ... }`, which
/// comes last by convention); a `#[cfg(test)] mod tests;` declaration is not a cut.
fn non_test_code(text: &str) -> &str {
    let mut from = 0;
    while let Some(at) = text[from..].find("#[cfg(test)]") {
        let at = from + at;
        let after = text[at + "#[cfg(test)]".len()..].trim_start();
        let inline = match (after.find('{'), after.find(';')) {
            (Some(brace), semicolon) => semicolon.is_none_or(|semicolon| brace < semicolon),
            (None, _) => false,
        };
        if after.starts_with("mod ") && inline {
            return &text[..at];
        }
        from = at + 1;
    }
    text
}

/// The error type of `Result<T, E>` from the text after `Result<`: what follows the comma at
/// the generics' top level, up to the closing `>` (`None` for a one-argument alias).
fn error_type(args: &str) -> Option<String> {
    let mut depth = 0;
    let mut comma = None;
    for (i, c) in args.char_indices() {
        match c {
            '<' | '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            '>' if depth == 0 => return comma.map(|at: usize| args[at + 1..i].trim().to_string()),
            '>' => depth -= 1,
            ',' if depth == 0 => comma = Some(i),
            _ => {}
        }
    }
    None
}

/// The engine's top-level modules: the loop's stages and state (`run`, `stages`), its
/// replay (`replay`), the radio (`comms`), the cameras rendered in the loop (`cameras`), what
/// a run returns (`output`) and the traits its sinks implement (`sinks`).
const ENGINE_MODULES: [&str; 7] = [
    "cameras", "comms", "output", "replay", "run", "sinks", "stages",
];

#[test]
fn the_engine_is_the_loop_and_the_radio() {
    let src = repo().join("sim/engine/src");
    let modules: BTreeSet<String> = sources(&src)
        .iter()
        .map(|f| top_module(&src, f))
        .filter(|m| m != "lib")
        .collect();
    assert_eq!(
        modules,
        ENGINE_MODULES.iter().map(|m| m.to_string()).collect(),
        "sim/engine/src holds other modules than the loop's"
    );
    let all = packages();
    let (_, deps) = &all["hetsim-engine"];
    for format in [
        "mcap",
        "zstd",
        "crc32fast",
        "cdr",
        "cdr-encoding",
        "byteorder",
        "image",
    ] {
        assert!(
            !deps.iter().any(|d| d == format),
            "hetsim-engine depends on {format}: file formats are hetsim-io's"
        );
    }
    assert!(all["hetsim-io"].1.iter().any(|d| d == "hetsim-engine"));
}

#[test]
fn each_heavy_dependency_lives_in_one_crate() {
    let all = packages();
    for (heavy, home) in [
        ("rapier3d-f64", "hetsim-physics"),
        ("wgpu", "hetsim-render"),
        ("clap", "hetsim-cli"),
        ("indicatif", "hetsim-cli"),
        ("anyhow", "hetsim-cli"),
    ] {
        let users: Vec<&String> = all
            .iter()
            .filter(|(_, (_, deps))| deps.iter().any(|d| d == heavy))
            .map(|(n, _)| n)
            .collect();
        assert_eq!(users, vec![home], "{heavy} is used by {users:?}");
    }
}

/// The crates `name` reaches through normal dependencies, itself included.
fn reachable(all: &BTreeMap<String, (String, Vec<String>)>, name: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![name.to_string()];
    while let Some(n) = todo.pop() {
        if seen.insert(n.clone()) {
            if let Some((_, deps)) = all.get(&n) {
                todo.extend(deps.iter().cloned());
            }
        }
    }
    seen
}

#[test]
fn one_camera_geometry_type_and_stacks_reach_no_renderer() {
    // A pinhole's parameters are declared once, in hetsim-msgs (`Pinhole`); everything else
    // uses that type.
    let mut declared = Vec::new();
    for dir in ["sim", "robots", "tests/src"] {
        for f in sources(&repo().join(dir)) {
            let text = std::fs::read_to_string(&f).unwrap();
            if text
                .lines()
                .any(|l| l.trim_start().starts_with("pub alpha_u: f64"))
            {
                declared.push(f.strip_prefix(repo()).unwrap().to_path_buf());
            }
        }
    }
    assert_eq!(
        declared,
        vec![PathBuf::from("robots/msgs/src/camera.rs")],
        "pinhole parameters declared outside hetsim-msgs"
    );
    let all = packages();
    let stacks = reachable(&all, "hetsim-stacks");
    assert!(
        !stacks.contains("hetsim-render") && !stacks.contains("hetsim-engine"),
        "hetsim-stacks reaches {stacks:?}"
    );
    // Evaluation runs missions through the engine, so it reaches the renderer there, but it
    // does not use it itself.
    assert!(!all["hetsim-eval"]
        .1
        .iter()
        .any(|d| d == "hetsim-render" || d == "wgpu"));
}

/// Every `.rs` file under a folder, sorted.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The top-level module a source file belongs to (`src/a.rs` and `src/a/b.rs` are `a`).
fn top_module(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

/// The top-level modules a file names through `crate::` paths (`crate::a::x`,
/// `crate::{a, b}`) outside comments (a doc link is not a dependency).
fn crate_references(text: &str) -> BTreeSet<String> {
    let code: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let text = code.as_str();
    let mut out = BTreeSet::new();
    for (i, _) in text.match_indices("crate::") {
        let rest = &text[i + "crate::".len()..];
        let names: Vec<&str> = if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            group[..end]
                .split(',')
                .map(|s| s.trim().split("::").next().unwrap_or("").trim())
                .collect()
        } else {
            vec![rest
                .split(|c: char| !(c.is_alphanumeric() || c == '_'))
                .next()
                .unwrap_or("")]
        };
        out.extend(
            names
                .into_iter()
                .filter(|n| !n.is_empty() && n.chars().next().unwrap().is_lowercase())
                .map(str::to_string),
        );
    }
    out
}

#[test]
fn no_crate_has_a_module_cycle() {
    for (name, (folder, _)) in packages() {
        let src = repo().join(&folder).join("src");
        if !src.is_dir() {
            continue;
        }
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        let files = sources(&src);
        let modules: BTreeSet<String> = files.iter().map(|f| top_module(&src, f)).collect();
        for f in &files {
            let from = top_module(&src, f);
            let text = std::fs::read_to_string(f).unwrap();
            for to in crate_references(&text) {
                if to != from && modules.contains(&to) && from != "lib" && from != "main" {
                    edges.entry(from.clone()).or_default().insert(to);
                }
            }
        }
        // Depth-first search for a back edge.
        fn visit(
            m: &str,
            edges: &BTreeMap<String, BTreeSet<String>>,
            path: &mut Vec<String>,
            done: &mut BTreeSet<String>,
        ) -> Option<Vec<String>> {
            if let Some(k) = path.iter().position(|p| p == m) {
                let mut cycle = path[k..].to_vec();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            if done.contains(m) {
                return None;
            }
            path.push(m.to_string());
            for next in edges.get(m).into_iter().flatten() {
                if let Some(c) = visit(next, edges, path, done) {
                    return Some(c);
                }
            }
            path.pop();
            done.insert(m.to_string());
            None
        }
        let mut done = BTreeSet::new();
        for m in edges.keys() {
            if let Some(cycle) = visit(m, &edges, &mut Vec::new(), &mut done) {
                panic!("{name}: module cycle {}", cycle.join(" -> "));
            }
        }
    }
}

/// The block of ARCHITECTURE.md between its `deps:begin` and `deps:end` markers, as `cargo
/// metadata` says it must read: one line per crate of ours, with the crates of ours it depends
/// on (normal dependencies), sorted.
fn dependency_block(all: &BTreeMap<String, (String, Vec<String>)>) -> String {
    let mut block = String::new();
    for (name, (folder, deps)) in all {
        let ours: BTreeSet<&String> = deps.iter().filter(|d| all.contains_key(*d)).collect();
        let list = if ours.is_empty() {
            "nothing of ours".to_string()
        } else {
            ours.iter()
                .map(|d| format!("`{d}`"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        block.push_str(&format!("- `{name}` (`{folder}`) -> {list}\n"));
    }
    block
}

#[test]
fn architecture_md_lists_the_dependencies_cargo_metadata_gives() {
    let all = packages();
    let path = repo().join("ARCHITECTURE.md");
    let text = std::fs::read_to_string(&path).unwrap();
    let (begin, end) = ("<!-- deps:begin -->\n", "<!-- deps:end -->");
    let from = text
        .find(begin)
        .expect("ARCHITECTURE.md has a deps:begin marker")
        + begin.len();
    let to = from
        + text[from..]
            .find(end)
            .expect("and a deps:end marker after it");
    let expected = dependency_block(&all);
    assert!(
        text[from..to] == expected,
        "{}'s dependency list has drifted from the Cargo.toml files; it must read:\n{expected}",
        path.display()
    );
}

#[test]
fn the_test_module_cut_keeps_code_after_a_test_module_declaration() {
    let text = "#[cfg(test)]\nmod tests;\nfn a() {}\n#[cfg(test)]\nmod more {\n fn b() {}\n}\n";
    assert_eq!(non_test_code(text), "#[cfg(test)]\nmod tests;\nfn a() {}\n");
}

#[test]
fn the_error_type_scanner_reads_nested_generics() {
    assert_eq!(error_type("(), String> {").as_deref(), Some("String"));
    assert_eq!(
        error_type("BTreeMap<String, String>, SceneError> {").as_deref(),
        Some("SceneError")
    );
    assert_eq!(error_type("Vec<(u8, String)>> {"), None);
}

#[test]
fn the_reference_scanner_sees_paths_and_groups() {
    let refs = crate_references(
        "use crate::{a::X, b};\nlet y = crate::c::f(); crate::Type;\n/// see [`crate::d`]",
    );
    assert_eq!(
        refs.into_iter().collect::<Vec<_>>(),
        vec!["a".to_string(), "b".into(), "c".into()]
    );
}
