//! `--help` prints every tool's and subcommand's examples as written, at
//! any terminal width: a command is never broken over two lines, so it
//! copies whole, while the options' descriptions still wrap.
//!
//! The examples as written come from the man page (`--generate man`), which
//! clap_mangen fills from the same `after_long_help` text without wrapping.

use std::process::Command;

use dem_testkit::{bin, ok, run, TOOLS};

/// Terminal widths the help is printed at.
const WIDTHS: [&str; 3] = ["40", "100", "200"];

/// The subcommands `TOOL --help` lists (without clap's `help`).
fn subcommands(tool: &str) -> Vec<String> {
    let help = dem_testkit::help(&[tool]);
    let after = help.split("\nCommands:\n").nth(1).unwrap_or_default();
    after
        .lines()
        .take_while(|l| l.starts_with("  "))
        .filter(|l| !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| *n != "help")
        .map(String::from)
        .collect()
}

/// Undo roff's escapes in a text line of clap_mangen's.
fn unroff(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match chars.next() {
            Some('-') => out.push('-'),
            Some('\\') | Some('e') => out.push('\\'),
            Some('&') => {}
            Some('*') => {
                let name: String = chars.by_ref().take(3).collect();
                assert_eq!(name, "(Aq", "unknown roff string in {line:?}");
                out.push('\'');
            }
            other => panic!("unknown roff escape \\{other:?} in {line:?}"),
        }
    }
    out
}

/// The examples section of `cmd`'s man page, as written (without the
/// `Examples:` heading, which the page turns into its section name).
fn examples_as_written(cmd: &[&str]) -> Option<String> {
    let mut args = vec!["--generate", "man"];
    args.extend(&cmd[1..]);
    let roff = String::from_utf8(ok(&run(cmd[0], &args, None)).to_vec()).unwrap();
    let at = roff.find(".SH EXAMPLES\n.nf\n")?;
    let body = &roff[at + ".SH EXAMPLES\n.nf\n".len()..];
    let body = &body[..body.find("\n.fi\n").expect("no-fill block ends")];
    Some(body.lines().map(unroff).collect::<Vec<_>>().join("\n"))
}

fn help_at(cmd: &[&str], width: &str) -> String {
    let o = Command::new(bin(cmd[0])).args(&cmd[1..]).arg("--help").env("COLUMNS", width).output().expect("spawn");
    String::from_utf8(ok(&o).to_vec()).unwrap()
}

#[test]
fn examples_are_never_wrapped_at_any_width() {
    let mut checked = 0;
    for tool in TOOLS {
        let subs = subcommands(tool);
        let mut cmds: Vec<Vec<&str>> = vec![vec![tool]];
        cmds.extend(subs.iter().map(|s| vec![tool, s.as_str()]));
        for cmd in cmds {
            let Some(examples) = examples_as_written(&cmd) else {
                assert!(cmd.len() == 2, "{tool} has no examples");
                continue;
            };
            let longest = examples.lines().map(str::len).max().unwrap_or(0);
            let mut before_lines = Vec::new();
            for width in WIDTHS {
                let help = help_at(&cmd, width);
                let block = format!("\n\nExamples:\n{examples}\n");
                let block1 = format!("\n\nExample:\n{examples}\n");
                assert!(
                    help.ends_with(&block) || help.ends_with(&block1),
                    "{cmd:?} --help at COLUMNS={width} does not end with its examples as written \
                     (longest line {longest}):\n{help}"
                );
                let head = &help[..help.rfind("\n\nExample").unwrap()];
                before_lines.push(head.lines().count());
            }
            // The options still wrap: fewer lines at 200 columns than at 40.
            assert!(before_lines[0] > before_lines[2], "{cmd:?}: help does not wrap at 40 columns: {before_lines:?}");
            checked += 1;
        }
    }
    assert!(checked >= 19, "{checked} commands with examples");
}

#[test]
fn help_subcommand_and_short_help_keep_their_forms() {
    // `TOOL help SUB` is `TOOL SUB --help`.
    let via_help = Command::new(bin("dem-eval")).args(["help", "compare"]).env("COLUMNS", "40").output().unwrap();
    assert_eq!(String::from_utf8_lossy(ok(&via_help)), help_at(&["dem-eval", "compare"], "40"));
    // -h is the summary, without examples, as clap prints it.
    let short = Command::new(bin("dem-render")).arg("-h").env("COLUMNS", "100").output().unwrap();
    let short = String::from_utf8_lossy(ok(&short)).into_owned();
    assert!(!short.contains("Examples:") && short.contains("see more with '--help'"), "{short}");
}
