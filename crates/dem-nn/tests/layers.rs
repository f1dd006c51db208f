//! The crate's modules form layers (see the crate docs): a module may use its
//! own layer and those below, never one above, and only tests may call the
//! f64 reference. This reads `src/`, collects every `crate::`, `super::` and
//! `self::` path per file (comments and literals stripped, `#[cfg(test)]`
//! items told apart) and checks both rules, plus that no two production
//! modules of one layer import each other in a circle.
//!
//! Test code may use modules of its own layer in any direction (a kernel's
//! test compares with another kernel), so the circle check reads production
//! code only.

use std::collections::BTreeMap;
use std::path::Path;

use dem_testkit::imports::{circles, edges, module_named, module_of, read_sources};

/// Top-level modules and their layers, bottom first. A new module must be
/// placed here before the test passes.
const LAYERS: &[(&str, usize)] = &[("gemm", 0), ("weights", 1), ("layers", 2), ("reference", 3), ("net", 4), ("train", 5)];

/// The one module that is the test oracle.
const ORACLE: &str = "reference";

#[test]
fn modules_import_only_their_own_layer_and_below() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let files = read_sources(&src);
    assert!(files.len() > 10, "read {} files from {}", files.len(), src.display());
    let problems = check(&files);
    assert!(problems.is_empty(), "dem-nn's modules break the layering:\n{}", problems.join("\n"));
}

/// The checker itself: an upward import, a production call of the reference
/// and a circle inside a layer are each caught, in every spelling; comments,
/// literals and test items are not mistaken for production imports.
#[test]
fn the_checker_catches_each_kind_of_break() {
    const BASE: [(&str, &str); 10] = [
        ("lib.rs", "pub mod gemm; pub mod layers; pub mod net; pub mod reference; pub mod train; pub mod weights;"),
        ("gemm.rs", ""),
        ("weights.rs", ""),
        ("layers/mod.rs", "pub mod conv; pub mod norm;"),
        ("layers/conv.rs", ""),
        ("layers/norm.rs", ""),
        ("reference.rs", "use crate::layers::conv::same_pad; use crate::weights::LEAK;"),
        ("net/mod.rs", "pub mod generator;"),
        ("net/generator.rs", "use crate::layers::conv; use super::super::weights::Arch;"),
        ("train/data.rs", "use crate::net::generator::Generator;"),
    ];
    let check_with = |changed: &[(&str, &str)]| {
        let mut files: Vec<(String, String)> = BASE.iter().map(|(p, s)| (p.to_string(), s.to_string())).collect();
        for (p, s) in changed {
            files.retain(|f| f.0 != *p);
            files.push((p.to_string(), s.to_string()));
        }
        check(&files)
    };
    let one = |changed: &[(&str, &str)], word: &str| {
        let p = check_with(changed);
        assert!(p.len() == 1 && p[0].contains(word), "{changed:?}: want one problem with {word:?}, got {p:?}");
    };
    assert_eq!(check_with(&[]), Vec::<String>::new());
    for upward in [
        "use crate::net::generator::GRID;",
        "use crate::{gemm, net};",
        "use crate::{gemm::{self, Mat}, layers::conv::ConvGeom as G};",
        "fn f() -> usize { crate::train::data::X }",
        "mod inner { use super::super::layers; }",
        "#[cfg(test)]\nmod tests {\n    use crate::net;\n}",
    ] {
        one(&[("weights.rs", upward)], "above it");
    }
    for oracle in [
        "use crate::reference;",
        "fn f() { let _ = crate::reference::generator(); }",
        "#[cfg(test)]\nfn g() -> [u8; 1] { [0] }\nuse crate::reference;",
        "#[cfg(test)]\nuse std::{fs, io};\nuse super::super::reference::generator;",
    ] {
        one(&[("layers/conv.rs", oracle)], "test oracle");
    }
    for fine in [
        "// use crate::net;\n/* crate::train /* nested */ */ const S: &str = \"crate::net\"; const R: &str = r#\"crate::net\"#;",
        "const C: char = '{'; const Q: char = '\\''; pub(crate) fn f<'a>(x: &'a u8) -> &'a u8 { x }",
        "#[cfg(test)]\nmod tests {\n    use super::*;\n    use crate::reference;\n}",
        "#[cfg(test)]\nuse crate::reference::generator;",
        "use crate::layers::norm; use self::inner::X; mod inner { use super::*; }",
    ] {
        assert_eq!(check_with(&[("layers/conv.rs", fine)]), Vec::<String>::new(), "{fine}");
    }
    one(&[("layers/norm.rs", "use crate::layers::conv::X;"), ("layers/conv.rs", "use super::norm::Y;")], "circle");
    one(&[("extra.rs", "")], "no layer");
}

fn layer(top: &str) -> Option<usize> {
    LAYERS.iter().find(|(m, _)| *m == top).map(|(_, l)| *l)
}

/// Every layering break in `files` (path under `src/`, text), one line each.
fn check(files: &[(String, String)]) -> Vec<String> {
    let modules: Vec<Vec<String>> = files.iter().map(|(p, _)| module_of(p)).collect();
    let mut problems = Vec::new();
    let mut graph: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for ((path, text), from) in files.iter().zip(&modules) {
        let Some(top) = from.first() else { continue };
        let Some(from_layer) = layer(top) else {
            problems.push(format!("{path}: module `{top}` has no layer in LAYERS"));
            continue;
        };
        for e in edges(from, text) {
            let Some(to) = module_named(&modules, &e.to) else {
                problems.push(format!("{path}:{}: `crate::{}` names no module with a layer", e.line, e.to.join("::")));
                continue;
            };
            if to == from {
                continue;
            }
            let to_layer = layer(&to[0]).unwrap_or(usize::MAX);
            let name = to.join("::");
            if to[0] == ORACLE && top != ORACLE {
                if !e.test {
                    problems.push(format!("{path}:{}: production code uses the test oracle `{name}`", e.line));
                }
            } else if to_layer > from_layer {
                problems.push(format!(
                    "{path}:{}: `{}` (layer {from_layer}) uses `{name}` (layer {to_layer}) above it",
                    e.line,
                    from.join("::")
                ));
            } else if !e.test {
                graph.entry(from.join("::")).or_default().push(name);
            }
        }
    }
    for circle in circles(&graph) {
        problems.push(format!("modules import each other in a circle: {}", circle.join(" -> ")));
    }
    problems
}
