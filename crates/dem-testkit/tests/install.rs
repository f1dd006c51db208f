//! What `make install` puts in place for every tool: its man page and
//! shell completions, generated from the same clap definition as `--help`
//! (`TOOL --generate KIND`).

use dem_testkit::{ok, run, stderr, TOOLS};

#[test]
fn every_tool_generates_its_man_page_and_completions() {
    // The list is the workspace's: a new tool is added to dem_testkit::TOOLS and the Makefile's TOOLS.
    let crates: Vec<String> = std::fs::read_dir(dem_testkit::workspace_root().join("crates"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| dem_testkit::workspace_root().join("crates").join(n).join("src/main.rs").exists())
        .collect();
    let mut sorted = crates.clone();
    sorted.sort();
    assert_eq!(sorted, TOOLS, "tools with a main.rs");
    let makefile = std::fs::read_to_string(dem_testkit::workspace_root().join("Makefile")).unwrap();
    let line = makefile.lines().find(|l| l.starts_with("TOOLS :=")).expect("Makefile TOOLS");
    assert_eq!(line.split_whitespace().skip(2).collect::<Vec<_>>(), TOOLS, "Makefile TOOLS");
    for tool in TOOLS {
        let gen = |kind: &str| String::from_utf8(ok(&run(tool, &["--generate", kind], None)).to_vec()).unwrap();
        let man = gen("man");
        assert!(man.contains(&format!(".TH {tool} 1")) && man.contains(".SH OPTIONS"), "{tool}: {man}");
        // The man page is --help's text: the first line of the about is there.
        let help = String::from_utf8(ok(&run(tool, &["--help"], None)).to_vec()).unwrap();
        // (--help wraps lines at the terminal's width; the page does not.)
        let about = help.split_whitespace().take(6).collect::<Vec<_>>().join(" ");
        assert!(man.replace("\\-", "-").replace("\\*(Aq", "'").contains(&about), "{tool}: {about:?} not in its man page");
        assert!(gen("bash").contains(&format!("complete -F _{}", tool.replace('-', "__"))), "{tool} bash");
        assert!(gen("zsh").starts_with(&format!("#compdef {tool}")), "{tool} zsh");
        assert!(gen("fish").contains(&format!("complete -c {tool}")), "{tool} fish");
    }
    let o = run("dem-cat", &["--generate", "tcsh"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("unknown kind 'tcsh'") && stderr(&o).lines().count() == 1, "{}", stderr(&o));
}
