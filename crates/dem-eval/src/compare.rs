//! `dem-eval compare`: two tables side by side, exit 1 when a row got worse.

use crate::table::forms::{self as report, read_table, Format};
use crate::table::{self, Compared, Status, Tolerances};
use dem_core::cli;

/// Compare `current` against `baseline`, print the comparison, fail when a row
/// is worse or missing; the message names the measures that failed.
pub fn run(baseline: &str, current: &str, tol: &Tolerances, format: Format) -> anyhow::Result<()> {
    for (flag, v) in [
        ("--tolerance", tol.pair),
        ("--height-tolerance", tol.height_cm),
        ("--rough-tolerance", tol.rough_cm),
        ("--gap-tolerance", tol.gap),
        ("--frame-dh-tolerance", tol.frame_dh_mm),
        ("--frame-tolerance", tol.frame),
    ] {
        if v.is_nan() || v < 0.0 {
            return Err(cli::usage(format!("{flag} must be a number >= 0")));
        }
    }
    let (b, c) = (read_table(baseline)?, read_table(current)?);
    let rows = table::compare(&b, &c, tol);
    report::write_comparison("-", &rows, format)?;
    for r in rows.iter().filter(|r| r.status == Status::Ok) {
        if let (Some(b), Some(c)) = (&r.baseline, &r.current) {
            if b.count != c.count {
                cli::log(format_args!("warning: {}/{}: {} records in the baseline, {} now", r.method, r.terrain, b.count, c.count));
            }
        }
    }
    let failed: Vec<String> = rows.iter().filter(|r| r.fails()).map(|r| describe(r, tol)).collect();
    if !failed.is_empty() {
        anyhow::bail!("{} of {} baseline rows failed: {}", failed.len(), b.len(), failed.join("; "));
    }
    cli::log(format_args!(
        "{} baseline rows within tolerance (pair error {}, height {} cm, roughness {} cm, gap {}, frame change {} mm, frame shares {})",
        b.len(),
        tol.pair,
        tol.height_cm,
        tol.rough_cm,
        tol.gap,
        tol.frame_dh_mm,
        tol.frame
    ));
    Ok(())
}

/// `method/terrain worse (height_cm +0.83 > 0.5, gap ...)` or `... missing`.
fn describe(r: &Compared, tol: &Tolerances) -> String {
    if r.status == Status::Missing {
        return format!("{}/{} missing", r.method, r.terrain);
    }
    let why: Vec<String> = r
        .worse
        .iter()
        .map(|&m| match r.diff(m) {
            Some(d) => format!("{} {d:+.4} > {}", m.name(), tol.of(m)),
            None => format!("{} absent", m.name()),
        })
        .collect();
    format!("{}/{} worse ({})", r.method, r.terrain, why.join(", "))
}
