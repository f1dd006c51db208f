//! What a trained model was made from and how: recorded in the run's
//! checkpoint when training starts, written into the exported ONNX file's
//! `metadata_props` (keys under `dem.`), read back by `dem-apply --info`.

use std::io::Read;

use dem_nn::train::checkpoint::{DataFile, Meta};
use sha2::{Digest, Sha256};

/// One input of a run, hashed (stdin is not: it cannot be read again).
pub fn data_file(role: &str, path: &str, records: Option<usize>) -> anyhow::Result<DataFile> {
    let sha256 = if path == "-" { None } else { Some(sha256_file(path)?) };
    Ok(DataFile { role: role.into(), path: path.into(), records, sha256 })
}

/// SHA-256 of a file's bytes, lower-case hex (what `sha256sum` prints).
pub fn sha256_file(path: &str) -> anyhow::Result<String> {
    let mut f = std::fs::File::open(path).map_err(|e| dem_core::DemError::input(path, format!("cannot read: {e}")))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(|e| dem_core::DemError::input(path, format!("cannot read: {e}")))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// The `metadata_props` of generator `which` (`y` or `x`) exported from a
/// run with checkpoint metadata `meta` and validation table `val_csv`.
pub fn export_metadata(meta: &Meta, which: &str, val_csv: Option<String>) -> Vec<(String, String)> {
    let c = &meta.config;
    let epochs = meta.step as f64 / meta.steps_per_epoch.max(1) as f64;
    let mut m = vec![
        ("dem.generator".into(), if which == "y" { "G_Y: sim -> real".into() } else { "G_X: real -> sim".to_string() }),
        ("dem.architecture".into(), format!("{} head, width {}", c.arch.name(), c.width)),
        ("dem.seed".into(), meta.seed.to_string()),
        (
            "dem.trained".into(),
            format!(
                "{} steps ({epochs:.2} epochs of {} steps), batch {}, paired fraction {}",
                meta.step, meta.steps_per_epoch, meta.batch, meta.paired_fraction
            ),
        ),
        ("dem.config".into(), serde_json::to_string(c).expect("config serialises")),
    ];
    for d in &meta.data {
        let mut v = d.path.clone();
        if let Some(n) = d.records {
            v += &format!(", {n} records");
        }
        if let Some(h) = &d.sha256 {
            v += &format!(", sha256 {h}");
        }
        m.push((format!("dem.data.{}", d.role), v));
    }
    if let Some(s) = &meta.sensor {
        m.push(("dem.sensor".into(), s.to_string()));
    }
    if let Some(v) = val_csv.filter(|v| v.lines().count() > 1) {
        m.push(("dem.validation".into(), v));
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_of_a_file_is_what_sha256sum_prints() {
        let dir = std::env::temp_dir().join(format!("dem-train-sha-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("abc.txt");
        std::fs::write(&p, b"abc").unwrap();
        // FIPS 180-2's example: SHA-256("abc").
        assert_eq!(sha256_file(p.to_str().unwrap()).unwrap(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
