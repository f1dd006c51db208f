//! What every binary shares at its edge: run, print the error once, decide
//! the exit code in one place; log lines and progress bars on stderr.
//!
//! Exit codes: 0 success (also when stdout was closed early, as by `| head`),
//! 2 bad input or usage, 1 internal failure.

use std::io::{self, IsTerminal, Write};
use std::process::ExitCode;

use indicatif::{ProgressBar, ProgressStyle};

use crate::error::DemError;

/// Run a tool's body and turn its outcome into the process exit code.
pub fn run(body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            let _ = writeln!(io::stderr(), "{}: error: {e:#}", program());
            ExitCode::from(exit_code(&e))
        }
    }
}

/// 2 when the chain holds a [`DemError`] about input or usage, else 1.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    e.chain()
        .find_map(|c| c.downcast_ref::<DemError>())
        .map_or(1, DemError::exit_code)
}

/// A closed stdout anywhere in the chain, also when a CSV or JSON writer
/// wrapped the I/O error into its own.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        let io = c.downcast_ref::<io::Error>();
        io.is_some_and(|io| io.kind() == io::ErrorKind::BrokenPipe || io.get_ref().is_some_and(|inner| wraps_broken_pipe(inner)))
            || wraps_broken_pipe(c)
    })
}

fn wraps_broken_pipe(e: &(dyn std::error::Error + 'static)) -> bool {
    let csv_pipe = e
        .downcast_ref::<csv::Error>()
        .is_some_and(|c| matches!(c.kind(), csv::ErrorKind::Io(io) if io.kind() == io::ErrorKind::BrokenPipe));
    let json_pipe = e.downcast_ref::<serde_json::Error>().is_some_and(|j| j.io_error_kind() == Some(io::ErrorKind::BrokenPipe));
    csv_pipe || json_pipe
}

/// The binary's name, for messages.
pub fn program() -> String {
    std::env::args()
        .next()
        .and_then(|a| std::path::Path::new(&a).file_name().map(|f| f.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "dem".into())
}

/// Write one log line to stderr, prefixed with the program name. Never panics
/// (a closed stderr is ignored).
pub fn log(msg: impl std::fmt::Display) {
    let _ = writeln!(io::stderr(), "{}: {msg}", program());
}

/// A progress bar over `len` items, drawn only when stderr is a terminal.
pub fn progress(len: u64, unit: &str) -> ProgressBar {
    if !io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let style = ProgressStyle::with_template(&format!(
        "{{spinner}} [{{elapsed_precise}}] {{bar:40}} {{pos}}/{{len}} {unit} ({{per_sec}}, eta {{eta}}) {{msg}}"
    ))
    .expect("valid template");
    ProgressBar::new(len).with_style(style)
}

/// Usage error (exit 2) with a message.
pub fn usage(msg: impl Into<String>) -> anyhow::Error {
    DemError::Usage(msg.into()).into()
}

/// A usage error when more than one of a tool's inputs is `-`: stdin can
/// be read once.
pub fn one_stdin<'a>(inputs: impl IntoIterator<Item = &'a str>) -> anyhow::Result<()> {
    if inputs.into_iter().filter(|p| *p == "-").count() > 1 {
        return Err(usage("only one input can be `-` (stdin)"));
    }
    Ok(())
}

/// Parse the command line; a usage error is one line naming the tool
/// (`dem-pair: error: invalid value 'nan' for '--max-error <M>': ...`),
/// exit 2. `--help` and `--version` print as clap does, exit 0.
///
/// `TOOL --generate KIND` (as the first argument, as ripgrep has it) prints
/// the tool's man page (`man`) or its completion script for a shell (`bash`,
/// `zsh`, `fish`, `elvish`, `powershell`) on stdout and exits: both come
/// from the same clap definition as `--help`, so they cannot drift from it.
pub fn parse<A: clap::Parser>() -> A {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--generate") {
        let code = match generate(A::command(), args.get(2).map(String::as_str).unwrap_or("")) {
            Ok(()) => 0,
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => 0,
            Err(e) => {
                let _ = writeln!(io::stderr(), "{}: error: --generate: {e}", program());
                2
            }
        };
        std::process::exit(code);
    }
    let parsed = negative_values(A::command()).try_get_matches().and_then(|m| A::from_arg_matches(&m));
    match parsed {
        Ok(a) => a,
        Err(e) => exit_on_clap_error(e),
    }
}

/// Kinds `--generate` knows.
pub const GENERATE_KINDS: [&str; 6] = ["man", "bash", "zsh", "fish", "elvish", "powershell"];

/// Write the man page or completion script `kind` of `cmd` to stdout.
fn generate(cmd: clap::Command, kind: &str) -> io::Result<()> {
    use clap_complete::Shell;
    let mut out = io::stdout().lock();
    let shell = match kind {
        "man" => return clap_mangen::Man::new(cmd).render(&mut out).and_then(|()| out.flush()),
        "bash" => Shell::Bash,
        "zsh" => Shell::Zsh,
        "fish" => Shell::Fish,
        "elvish" => Shell::Elvish,
        "powershell" => Shell::PowerShell,
        _ => {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("unknown kind '{kind}', expected one of {}", GENERATE_KINDS.join(", ")),
            ))
        }
    };
    let mut cmd = cmd;
    let name = cmd.get_name().to_string();
    clap_complete::generate(shell, &mut cmd, name, &mut out);
    out.flush()
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

/// clap value parsers for numbers that must make sense: finite (no `nan`,
/// `inf`), and inside the range a tool can use. Each error says what is
/// expected, so clap's message reads "invalid value 'nan' for '`--lr <LR>`':
/// must be a finite number > 0".
pub mod value {
    use std::str::FromStr;

    fn number<T: FromStr + Copy + Into<f64>>(s: &str, ok: impl Fn(f64) -> bool, what: &str) -> Result<T, String> {
        let v: T = s.trim().parse().map_err(|_| format!("not a number, expected {what}"))?;
        let x: f64 = v.into();
        if x.is_finite() && ok(x) {
            Ok(v)
        } else {
            Err(format!("must be {what}"))
        }
    }

    /// Any finite number.
    pub fn finite<T: FromStr + Copy + Into<f64>>(s: &str) -> Result<T, String> {
        number(s, |_| true, "a finite number")
    }

    /// A finite number > 0.
    pub fn positive<T: FromStr + Copy + Into<f64>>(s: &str) -> Result<T, String> {
        number(s, |x| x > 0.0, "a finite number > 0")
    }

    /// A finite number >= 0.
    pub fn non_negative<T: FromStr + Copy + Into<f64>>(s: &str) -> Result<T, String> {
        number(s, |x| x >= 0.0, "a finite number >= 0")
    }

    /// A fraction in 0..=1.
    pub fn fraction<T: FromStr + Copy + Into<f64>>(s: &str) -> Result<T, String> {
        number(s, |x| (0.0..=1.0).contains(&x), "a fraction in 0..1")
    }

    /// A count of at least 1 (threads, runs, epochs, steps, batch sizes).
    pub fn at_least_one<T: FromStr + PartialOrd + From<u8>>(s: &str) -> Result<T, String> {
        match s.trim().parse::<T>() {
            Ok(v) if v >= T::from(1) => Ok(v),
            _ => Err("must be a whole number >= 1".into()),
        }
    }

    /// A finite number in `lo..=hi`, for flags with a physical range.
    pub fn within(s: &str, lo: f64, hi: f64) -> Result<f64, String> {
        number(s, |x| (lo..=hi).contains(&x), &format!("a finite number in {lo}..={hi}"))
    }
}
