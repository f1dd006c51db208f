//! No two modules of a crate import each other in a circle, in any crate of
//! the workspace: each crate's files form layers a newcomer can read bottom
//! up. Test code may reach anywhere; production code may not circle.

use dem_testkit::imports::{circles, production_graph, read_sources};
use dem_testkit::workspace_root;

#[test]
fn no_crate_has_modules_that_import_each_other_in_a_circle() {
    let mut problems = Vec::new();
    let mut crates = 0;
    for entry in std::fs::read_dir(workspace_root().join("crates")).expect("crates/").flatten() {
        let src = entry.path().join("src");
        if !src.is_dir() {
            continue;
        }
        crates += 1;
        let name = entry.file_name().to_string_lossy().into_owned();
        for c in circles(&production_graph(&read_sources(&src))) {
            problems.push(format!("{name}: {}", c.join(" -> ")));
        }
    }
    assert!(crates > 15, "read {crates} crates");
    assert!(problems.is_empty(), "modules import each other in a circle:\n{}", problems.join("\n"));
}

/// The checker: a circle through production imports is found, in either
/// spelling; a child reading its parent, and test code, are not circles.
#[test]
fn the_checker_finds_a_circle_and_only_a_circle() {
    let files = |b_rs: &str| -> Vec<(String, String)> {
        [
            ("lib.rs", "pub mod a; pub mod b; pub mod c;"),
            ("a.rs", "use crate::b::X; pub mod inner;"),
            ("a/inner.rs", "use super::Y;"),
            ("b.rs", b_rs),
            ("c.rs", "use crate::a::inner::Z;"),
        ]
        .iter()
        .map(|(p, s)| (p.to_string(), s.to_string()))
        .collect()
    };
    assert!(circles(&production_graph(&files("use crate::c::W;"))).is_empty());
    assert!(circles(&production_graph(&files("#[cfg(test)]\nmod tests { use crate::a::Y; }"))).is_empty());
    for circle in ["use crate::a::Y;", "fn f() { super::a::g() }", "use crate::{c::W, a as other};"] {
        let found = circles(&production_graph(&files(circle)));
        assert_eq!(found.len(), 1, "{circle}: {found:?}");
    }
}
