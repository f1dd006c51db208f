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

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<io::Error>().is_some_and(|io| io.kind() == io::ErrorKind::BrokenPipe)
    })
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
