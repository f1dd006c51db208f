//! dem-fill-nans on the bundled measured data.

use dem_core::format::{DemCells, COLS, GRID_ROWS};
use dem_core::npy;
use dem_fill_nans::missing_fraction;
use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

fn heights(d: &dem_core::Dem) -> Vec<u32> {
    (0..GRID_ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .filter(|&(r, c)| d.is_valid(r, c))
        .map(|(r, c)| d.height(r, c).to_bits())
        .collect()
}

#[test]
fn filled_records_are_whole_with_their_own_heights_the_rest_untouched() {
    let dir = tempdir();
    let out = arg(dir.path(), "f.npy");
    let o = run("dem-fill-nans", &["--min-missing", "0.3", "--keep", "10", "--seed", "4", &td("real.npy"), "-o", &out], None);
    ok(&o);
    let (input, filled) = (npy::read_all(&td("real.npy")).unwrap(), npy::read_all(&out).unwrap());
    assert_eq!(input.len(), filled.len());
    let (mut large, mut kept, mut changed) = (0, 0, 0);
    for (a, b) in input.iter().zip(&filled) {
        if missing_fraction(a) < 0.3 {
            assert_eq!(a, b, "small-missing record changed");
            continue;
        }
        large += 1;
        if a == b {
            kept += 1;
            continue;
        }
        changed += 1;
        assert_eq!(b.valid_cells(), 100, "filled record still has holes");
        let own: std::collections::HashSet<u32> = heights(a).into_iter().collect();
        assert!(heights(b).iter().all(|h| own.contains(h)), "a height the record did not have");
        assert_eq!(a.attitude(), b.attitude());
    }
    assert_eq!(kept, 10);
    assert!(changed > 50, "{changed} of {large}");
    assert!(stderr(&o).contains(&format!("kept 10, filled {changed}")), "{}", stderr(&o));
    // Same seed, same output; another seed, other draws.
    let again = arg(dir.path(), "g.npy");
    ok(&run("dem-fill-nans", &["--min-missing", "0.3", "--keep", "10", "--seed", "4", &td("real.npy"), "-o", &again], None));
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
}

#[test]
fn keep_fraction_streams_and_keep_n_needs_a_file() {
    let o = run("dem-fill-nans", &["--keep-fraction", "0.5"], Some(std::fs::read(td("real.npy")).unwrap()));
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert_eq!(out.len(), 966);
    assert!(stderr(&o).contains("kept"), "{}", stderr(&o));
    let o = run("dem-fill-nans", &["--keep", "3"], Some(std::fs::read(td("real.npy")).unwrap()));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--keep"));
}
