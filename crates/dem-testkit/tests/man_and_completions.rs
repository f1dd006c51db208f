//! Man pages and completion scripts cover every subcommand: each tool writes
//! its page and one page per subcommand (`TOOL --generate man --out-dir
//! DIR`), each page renders with `man -l` (groff when `man` is missing) and
//! names its options, every page a page names exists, and the bash script
//! completes each subcommand's flags when bash calls it as bash-completion
//! does (the zsh and fish scripts are checked by their text).

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use dem_testkit::{ok, run, stderr, tempdir, TOOLS};

fn text(out: &[u8]) -> String {
    String::from_utf8(out.to_vec()).expect("UTF-8")
}

/// The subcommands `TOOL --help` lists (without clap's `help`).
fn subcommands(tool: &str) -> Vec<String> {
    let help = dem_testkit::help(&[tool]);
    let mut subs = Vec::new();
    let mut inside = false;
    for line in help.lines() {
        if line.starts_with("Commands:") {
            inside = true;
        } else if inside && line.starts_with("  ") && !line.starts_with("   ") {
            let name = line.split_whitespace().next().unwrap_or_default();
            if name != "help" {
                subs.push(name.to_string());
            }
        } else if inside && !line.starts_with(' ') {
            break;
        }
    }
    subs
}

/// The long flags `--help` of `cmd` (`["dem-train", "export"]`) lists.
fn long_flags(cmd: &[&str]) -> Vec<String> {
    let help = dem_testkit::help(cmd);
    let mut flags = Vec::new();
    for line in help.lines().take_while(|l| !l.starts_with("Example")) {
        let t = line.trim_start();
        if !t.starts_with('-') || !line.starts_with("  ") || line.len() - t.len() > 6 {
            continue;
        }
        for word in t.split_whitespace().take(2) {
            let word = word.trim_end_matches(',');
            if let Some(name) = word.strip_prefix("--") {
                let name = name.split(['=', '<', '[']).next().unwrap_or_default();
                flags.push(format!("--{name}"));
            }
        }
    }
    assert!(flags.contains(&"--help".to_string()), "{cmd:?}: no flags found in its help:\n{help}");
    flags
}

/// A page rendered as a reader sees it: `man -l` when `man` is on PATH,
/// else `groff -man -Tutf8`; overstrikes removed, typographic dashes as `-`.
fn render(page: &Path) -> String {
    let has_man = Command::new("man").arg("--version").output().is_ok_and(|o| o.status.success());
    let out = if has_man {
        Command::new("man")
            .arg("-l")
            .arg(page)
            .env("MANWIDTH", "250")
            .env("MANPAGER", "cat")
            .env("PAGER", "cat")
            .env_remove("MAN_KEEP_FORMATTING")
            .output()
            .expect("run man")
    } else {
        Command::new("groff").args(["-man", "-Tutf8", "-P-cbou", "-rLL=250n"]).arg(page).output().expect("run groff (or man)")
    };
    assert!(out.status.success(), "{} does not render: {}", page.display(), String::from_utf8_lossy(&out.stderr));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"), "{}: {}", page.display(), String::from_utf8_lossy(&out.stderr));
    let raw = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut plain = String::with_capacity(raw.len());
    for c in raw.chars() {
        if c == '\u{8}' {
            plain.pop();
        } else {
            plain.push(c);
        }
    }
    plain.replace(['\u{2010}', '\u{2212}'], "-")
}

/// The page names a roff page refers to, as `name(1)`.
fn references(roff: &str) -> BTreeSet<String> {
    let plain = roff.replace("\\-", "-").replace("\\fB", "").replace("\\fR", "").replace("\\fI", "");
    let mut refs = BTreeSet::new();
    for (at, _) in plain.match_indices("(1)") {
        let before = &plain[..at];
        let start = before.rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '-')).map_or(0, |i| i + 1);
        if before[start..].starts_with("dem-") {
            refs.insert(before[start..].to_string());
        }
    }
    refs
}

#[test]
fn every_tool_and_subcommand_has_a_man_page_that_names_its_options() {
    let mut pages_seen = 0;
    for tool in TOOLS {
        let dir = tempdir();
        let d = dir.path().join("man1");
        ok(&run(tool, &["--generate", "man", "--out-dir", d.to_str().unwrap()], None));
        let subs = subcommands(tool);
        let mut expected: BTreeSet<String> = subs.iter().map(|s| format!("{tool}-{s}.1")).collect();
        expected.insert(format!("{tool}.1"));
        let written: BTreeSet<String> =
            std::fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        assert_eq!(written, expected, "{tool}: pages written");
        // The page on stdout is the one in the directory.
        let top = text(ok(&run(tool, &["--generate", "man"], None)));
        assert_eq!(top, std::fs::read_to_string(d.join(format!("{tool}.1"))).unwrap(), "{tool}: --generate man");
        let mut cmds: Vec<Vec<&str>> = vec![vec![tool]];
        cmds.extend(subs.iter().map(|s| vec![tool, s.as_str()]));
        for cmd in &cmds {
            let name = cmd.join("-");
            let path = d.join(format!("{name}.1"));
            let roff = std::fs::read_to_string(&path).unwrap();
            if let [_, sub] = cmd.as_slice() {
                assert_eq!(text(ok(&run(tool, &["--generate", "man", sub], None))), roff, "{tool} --generate man {sub}");
            }
            let page = render(&path);
            assert!(page.contains(&format!("{name}(1)")) && page.contains("NAME") && page.contains("OPTIONS"), "{name}:\n{page}");
            for flag in long_flags(cmd) {
                assert!(page.contains(&flag), "{name}: its page does not name {flag}:\n{page}");
            }
            if cmd.len() == 2 {
                assert!(page.contains("SEE ALSO") && page.contains(&format!("{tool}(1)")), "{name}: no SEE ALSO of {tool}(1)");
            }
            // Every page a page names exists: this tool's, or another tool's.
            for r in references(&roff) {
                let exists = written.contains(&format!("{r}.1")) || TOOLS.contains(&r.as_str());
                assert!(exists, "{name} names {r}(1), which is not generated");
            }
            // Examples are set as written (no-fill): a command stays on its line.
            if roff.contains(".SH EXAMPLES") {
                assert!(roff.contains(".SH EXAMPLES\n.nf\n"), "{name}: examples are filled");
            }
            pages_seen += 1;
        }
    }
    assert!(pages_seen >= TOOLS.len() + 9, "{pages_seen} pages");
    // `dem-sensor apply`'s page names the options the tool's page never had.
    let dir = tempdir();
    let page = dir.path().join("dem-sensor-apply.1");
    std::fs::write(&page, ok(&run("dem-sensor", &["--generate", "man", "apply"], None))).unwrap();
    let page = render(&page);
    for flag in ["--seed", "--first-index", "--only"] {
        assert!(page.contains(flag), "{flag} not in dem-sensor-apply(1)");
    }
}

#[test]
fn man_generation_refuses_what_it_does_not_know() {
    let o = run("dem-train", &["--generate", "man", "nope"], None);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("no subcommand 'nope'") && e.contains("export") && e.lines().count() == 1, "{e}");
    let o = run("dem-cat", &["--generate", "man", "--out-dir"], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = run("dem-cat", &["--generate", "bash", "extra"], None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// What the bash completion offers for `words` (the last is the word under
/// the cursor), calling the script's function as bash-completion does.
fn bash_complete(script: &Path, tool: &str, cases: &[Vec<String>]) -> Vec<Vec<String>> {
    let func = format!("_{}", tool.replace('-', "__"));
    let mut body = format!("source '{}' || exit 3\n", script.display());
    for words in cases {
        let quoted: Vec<String> = words.iter().map(|w| format!("'{w}'")).collect();
        let cword = words.len() - 1;
        let prev = if cword > 0 { quoted[cword - 1].clone() } else { "''".into() };
        body.push_str(&format!(
            "COMP_WORDS=({}); COMP_CWORD={cword}; COMPREPLY=(); {func} '{tool}' {} {prev}; echo \"${{COMPREPLY[*]}}\"\n",
            quoted.join(" "),
            quoted[cword],
        ));
    }
    let o = Command::new("bash").args(["--norc", "--noprofile", "-c", &body]).output().expect("run bash");
    assert!(o.status.success(), "bash: {}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<Vec<String>> =
        String::from_utf8_lossy(&o.stdout).lines().map(|l| l.split_whitespace().map(String::from).collect()).collect();
    assert_eq!(lines.len(), cases.len(), "{}", String::from_utf8_lossy(&o.stdout));
    lines
}

#[test]
fn completions_complete_every_subcommands_flags() {
    for tool in TOOLS {
        let dir = tempdir();
        let script = dir.path().join(tool);
        std::fs::write(&script, ok(&run(tool, &["--generate", "bash"], None))).unwrap();
        let zsh = text(ok(&run(tool, &["--generate", "zsh"], None)));
        let fish = text(ok(&run(tool, &["--generate", "fish"], None)));
        let subs = subcommands(tool);
        let mut cmds: Vec<Vec<String>> = vec![vec![tool.to_string()]];
        cmds.extend(subs.iter().map(|s| vec![tool.to_string(), s.clone()]));
        let cases: Vec<Vec<String>> = cmds.iter().map(|c| c.iter().cloned().chain(["--".to_string()]).collect()).collect();
        let replies = bash_complete(&script, tool, &cases);
        for (cmd, reply) in cmds.iter().zip(&replies) {
            let cmd: Vec<&str> = cmd.iter().map(String::as_str).collect();
            for flag in long_flags(&cmd) {
                assert!(reply.contains(&flag), "bash: `{} --<TAB>` does not offer {flag}: {reply:?}", cmd.join(" "));
            }
            let [_, sub] = cmd.as_slice() else { continue };
            let fish_fn = format!("__fish_{}_using_subcommand {sub}\"", tool.replace('-', "_"));
            // The first `(SUB)` arm of the zsh script holds SUB's arguments.
            let arm: String =
                zsh.lines().skip_while(|l| l.trim() != format!("({sub})")).take_while(|l| l.trim() != ";;").collect::<Vec<_>>().join("\n");
            assert!(!arm.is_empty(), "zsh: no arm for {tool} {sub}");
            for flag in long_flags(&cmd) {
                let long = flag.trim_start_matches("--");
                assert!(arm.contains(&format!("{flag}=[")) || arm.contains(&format!("{flag}[")), "zsh: {tool} {sub} {flag}");
                let fish_has = |l: &str| l.split_whitespace().collect::<Vec<_>>().windows(2).any(|w| w == ["-l", long]);
                assert!(fish.lines().any(|l| l.contains(&fish_fn) && fish_has(l)), "fish: {tool} {sub} {flag}");
            }
        }
    }
    // The case of the report: `dem-train export --re<TAB>`.
    let dir = tempdir();
    let script = dir.path().join("dem-train");
    std::fs::write(&script, ok(&run("dem-train", &["--generate", "bash"], None))).unwrap();
    let words = ["dem-train", "export", "--re"].map(String::from).to_vec();
    assert_eq!(bash_complete(&script, "dem-train", &[words]), [vec!["--residual".to_string()]]);
}
