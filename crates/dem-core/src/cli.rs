//! What every binary shares at its edge: run, print the error once, decide
//! the exit code in one place; log lines and progress bars on stderr.
//!
//! Exit codes: 0 success (also when stdout was closed early, as by `| head`),
//! 2 bad input or usage, 1 internal failure.

use std::io::{self, Write};
use std::process::ExitCode;

use crate::error::DemError;

// The argument parser, man pages, completions and progress bars pull in
// clap and indicatif: a library that only needs the contract (dem-nn) goes
// without them.
#[cfg(feature = "cli")]
mod parse;
#[cfg(feature = "cli")]
pub use parse::parse;

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
    e.chain().find_map(|c| c.downcast_ref::<DemError>()).map_or(1, DemError::exit_code)
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
#[cfg(feature = "cli")]
pub fn progress(len: u64, unit: &str) -> indicatif::ProgressBar {
    use indicatif::{ProgressBar, ProgressStyle};
    use std::io::IsTerminal;
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
