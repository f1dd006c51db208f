//! The command line of a tool: parse it (one-line usage errors), and its
//! man pages and completion scripts from the same clap definition.

use std::io::{self, Write};

use super::program;

/// Parse the command line; a usage error is one line naming the tool
/// (`dem-pair: error: invalid value 'nan' for '--max-error <M>': ...`),
/// exit 2. `--help` and `--version` print as clap does, exit 0, except that
/// the examples after the options (`after_long_help`) are printed as
/// written, never wrapped at the terminal's width, so every example copies
/// whole; the options' descriptions still wrap.
///
/// `TOOL --generate KIND` (as the first argument, as ripgrep has it) prints
/// the tool's man page or its completion script on stdout and exits: both
/// come from the same clap definition as `--help`, so they cannot drift from
/// it. Kinds:
/// - `man`: the tool's page; `man SUB` the page of its subcommand SUB
///   (`TOOL-SUB(1)`); `man --out-dir DIR` writes every page (`TOOL.1` and one
///   `TOOL-SUB.1` per subcommand) into DIR;
/// - `bash`, `zsh`, `fish`, `elvish`, `powershell`: the completion script,
///   which completes the tool's flags and each subcommand's.
pub fn parse<A: clap::Parser>() -> A {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--generate") {
        let code = match generate(A::command(), &args[2..]) {
            Ok(()) => 0,
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => 0,
            Err(e) => {
                let _ = writeln!(io::stderr(), "{}: error: --generate: {e}", program());
                2
            }
        };
        std::process::exit(code);
    }
    let mut cmd = examples_unwrapped(negative_values(A::command()));
    let parsed = cmd.try_get_matches_from_mut(std::env::args_os()).and_then(|m| A::from_arg_matches(&m));
    match parsed {
        Ok(a) => a,
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => print_help(&mut cmd, &e),
        Err(e) => exit_on_clap_error(e),
    }
}

/// Kinds `--generate` knows.
pub const GENERATE_KINDS: [&str; 6] = ["man", "bash", "zsh", "fish", "elvish", "powershell"];

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// Write what `--generate ARGS` asks for (see [`parse`]).
fn generate(cmd: clap::Command, args: &[String]) -> io::Result<()> {
    use clap_complete::Shell;
    let kind = args.first().map_or("", String::as_str);
    let rest = args.get(1..).unwrap_or_default();
    let shell = match kind {
        "man" => return generate_man(cmd, rest),
        "bash" => Shell::Bash,
        "zsh" => Shell::Zsh,
        "fish" => Shell::Fish,
        "elvish" => Shell::Elvish,
        "powershell" => Shell::PowerShell,
        _ => return Err(invalid(format!("unknown kind '{kind}', expected one of {}", GENERATE_KINDS.join(", ")))),
    };
    if let Some(extra) = rest.first() {
        return Err(invalid(format!("unexpected argument '{extra}' after '{kind}'")));
    }
    let mut cmd = cmd;
    let name = cmd.get_name().to_string();
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut cmd, name.clone(), &mut script);
    let mut script = String::from_utf8(script).map_err(|e| invalid(e.to_string()))?;
    if shell == Shell::Bash {
        script = bash_case_labels(&script, &name);
    }
    let mut out = io::stdout().lock();
    out.write_all(script.as_bytes())?;
    out.flush()
}

/// clap_complete's bash script walks the command line into a state spelled
/// `dem__train__subcmd__export` but labels that state's case arm
/// `dem__subcmd__train__subcmd__export` when the binary's name holds a dash,
/// so no subcommand's flags complete. Spell the labels as the walk does (a
/// no-op for a generator that already agrees).
fn bash_case_labels(script: &str, bin: &str) -> String {
    if !bin.contains('-') {
        return script.to_string();
    }
    let label = format!("{}__subcmd__", bin.replace('-', "__subcmd__"));
    let state = format!("{}__subcmd__", bin.replace('-', "__"));
    script.replace(&label, &state)
}

/// `--generate man [SUB | --out-dir DIR]`.
fn generate_man(cmd: clap::Command, args: &[String]) -> io::Result<()> {
    let mut root = cmd.disable_help_subcommand(true);
    root.build();
    match args {
        [] => write_stdout(&man_page(&root, None)),
        [flag, dir] if flag == "--out-dir" => {
            let dir = std::path::Path::new(dir);
            std::fs::create_dir_all(dir)?;
            let mut pages = vec![(root.get_name().to_string(), man_page(&root, None))];
            for sub in root.get_subcommands().filter(|s| !s.is_hide_set()) {
                pages.push((page_name(sub), man_page(sub, Some(&root))));
            }
            for (name, page) in pages {
                let path = dir.join(format!("{name}.1"));
                std::fs::write(&path, page).map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
            }
            Ok(())
        }
        [flag] if flag == "--out-dir" => Err(invalid("--out-dir needs a directory".into())),
        [sub] => match root.find_subcommand(sub).filter(|s| !s.is_hide_set()) {
            Some(s) => write_stdout(&man_page(s, Some(&root))),
            None => {
                let subs: Vec<&str> = root.get_subcommands().filter(|s| !s.is_hide_set()).map(|s| s.get_name()).collect();
                let known = if subs.is_empty() { "it has none".to_string() } else { format!("expected one of {}", subs.join(", ")) };
                Err(invalid(format!("'{}' has no subcommand '{sub}' ({known})", root.get_name())))
            }
        },
        _ => Err(invalid(format!("unexpected argument '{}' after 'man'", args[1]))),
    }
}

fn write_stdout(bytes: &[u8]) -> io::Result<()> {
    let mut out = io::stdout().lock();
    out.write_all(bytes)?;
    out.flush()
}

/// A page's name: `dem-train` for a tool, `dem-train-export` for a
/// subcommand (clap's display name once the tool's command is built).
fn page_name(cmd: &clap::Command) -> String {
    cmd.get_display_name().unwrap_or_else(|| cmd.get_name()).to_string()
}

/// The roff page of `cmd` (a built tool, or one of its subcommands with its
/// `parent`): clap_mangen's page, with the examples set as written (no-fill,
/// under EXAMPLES) and a SEE ALSO section naming the tool's other pages.
fn man_page(cmd: &clap::Command, parent: Option<&clap::Command>) -> Vec<u8> {
    let tool = parent.unwrap_or(cmd);
    let source = format!("{} {}", tool.get_name(), tool.get_version().unwrap_or_default());
    let mut roff = Vec::new();
    clap_mangen::Man::new(cmd.clone()).source(source.trim_end()).render(&mut roff).expect("writing to a Vec");
    let roff = String::from_utf8(roff).expect("clap_mangen writes UTF-8");
    let mut out = String::with_capacity(roff.len() + 256);
    let mut lines = roff.lines().peekable();
    while let Some(line) = lines.next() {
        if line != ".SH EXTRA" {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        let mut body: Vec<&str> = Vec::new();
        while let Some(next) = lines.next_if(|l| !l.starts_with(".SH ")) {
            body.push(next);
        }
        match body.first() {
            Some(first) if *first == "Examples:" || *first == "Example:" => {
                out.push_str(".SH EXAMPLES\n");
                body.remove(0);
            }
            _ => out.push_str(".SH EXTRA\n"),
        }
        out.push_str(".nf\n");
        for b in body {
            out.push_str(b);
            out.push('\n');
        }
        out.push_str(".fi\n");
    }
    let mut see: Vec<String> = std::iter::once(page_name(tool))
        .chain(tool.get_subcommands().filter(|s| !s.is_hide_set()).map(page_name))
        .filter(|n| *n != page_name(cmd))
        .collect();
    see.dedup();
    if !see.is_empty() {
        let refs: Vec<String> = see.iter().map(|n| format!("\\fB{}\\fR(1)", n.replace('-', "\\-"))).collect();
        out.push_str(".SH \"SEE ALSO\"\n");
        out.push_str(&refs.join(", "));
        out.push('\n');
    }
    out.into_bytes()
}

/// clap's help without its after-help section: [`print_help`] prints that
/// section as written, where clap would wrap it at the terminal's width
/// (breaking an example in two).
const HELP_TEMPLATE: &str = "{before-help}{about-with-newline}\n{usage-heading} {usage}\n\n{all-args}";

fn examples_unwrapped(cmd: clap::Command) -> clap::Command {
    let cmd = if cmd.get_after_help().is_some() || cmd.get_after_long_help().is_some() { cmd.help_template(HELP_TEMPLATE) } else { cmd };
    cmd.mut_subcommands(examples_unwrapped)
}

/// Print the help clap rendered into `e` (for the tool or one of its
/// subcommands, short or long), then that command's after-help text as
/// written, as clap places it; exit 0.
fn print_help(cmd: &mut clap::Command, e: &clap::Error) -> ! {
    let shown = e.render().to_string();
    cmd.build();
    let after = after_help_of(cmd, &shown).flatten();
    let _ = e.print();
    if let Some(text) = after {
        let mut out = io::stdout().lock();
        let _ = write!(out, "\n{}\n", text.replace("{n}", "\n").trim_end()).and_then(|()| out.flush());
    }
    std::process::exit(0)
}

/// The after-help text of the command whose help is `shown`: `Some(None)`
/// when that command has none, `None` when no command renders as `shown`.
fn after_help_of(cmd: &mut clap::Command, shown: &str) -> Option<Option<String>> {
    if cmd.render_long_help().to_string() == shown {
        return Some(cmd.get_after_long_help().or_else(|| cmd.get_after_help()).map(ToString::to_string));
    }
    if cmd.render_help().to_string() == shown {
        return Some(cmd.get_after_help().map(ToString::to_string));
    }
    cmd.get_subcommands_mut().find_map(|s| after_help_of(s, shown))
}

/// Let every option take a value that starts with `-` and a digit, so
/// `--seed -1` is refused as a bad value of `--seed`, not as an unknown
/// argument `-1` that names no flag.
fn negative_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        let takes_values = a.get_action().takes_values() && a.get_num_args().is_none_or(|n| n.takes_values());
        if takes_values {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_values)
}

fn exit_on_clap_error(e: clap::Error) -> ! {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand) {
        e.exit()
    }
    let _ = writeln!(io::stderr(), "{}: error: {} (see --help)", program(), clap_one_line(&e.render().to_string()));
    std::process::exit(2)
}

/// The first paragraph of clap's rendered error, on one line, without its
/// `error:` prefix (the tips and usage that follow are left out).
fn clap_one_line(rendered: &str) -> String {
    let first: Vec<&str> = rendered.lines().take_while(|l| !l.trim().is_empty()).map(str::trim).collect();
    let text = first.join(" ");
    text.strip_prefix("error: ").unwrap_or(&text).to_string()
}
