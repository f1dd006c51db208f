//! dem-clean-pallet on the bundled sim data: only pallets change, no stripe is left.

use dem_clean_pallet::{gap_cells, looks_like_pallet, StripeRule};
use dem_core::{npy, table, Terrain};
use dem_testkit::{arg, ok, run, stderr, tempdir, testdata};

fn td(name: &str) -> String {
    testdata(name).to_string_lossy().into_owned()
}

#[test]
fn cleaning_changes_only_pallets_and_leaves_no_stripe() {
    let dir = tempdir();
    let input = npy::read_all(&td("sim.npy")).unwrap();
    let labels = table::read_labels(&td("sim_labels.csv")).unwrap();
    let rule = StripeRule::default();
    let striped_before = input.iter().filter(|d| looks_like_pallet(&gap_cells(d, &rule), &rule)).count();
    assert!(striped_before > 100, "sim pallets show stripes");
    for with_labels in [true, false] {
        let out = arg(dir.path(), "c.npy");
        let mut args = vec![td("sim.npy"), "-o".into(), out.clone()];
        if with_labels {
            args.extend(["--labels".into(), td("sim_labels.csv")]);
        }
        let o = run("dem-clean-pallet", &args.iter().map(String::as_str).collect::<Vec<_>>(), None);
        ok(&o);
        let cleaned = npy::read_all(&out).unwrap();
        assert_eq!(cleaned.len(), input.len());
        let mut changed = 0;
        for ((a, b), l) in input.iter().zip(&cleaned).zip(&labels) {
            let bits = |d: &dem_core::Dem| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            if bits(a) != bits(b) {
                changed += 1;
                assert_eq!(l.terrain, Terrain::Pallet, "record {} ({}) changed", l.index, l.terrain);
            }
            if l.terrain == Terrain::Pallet {
                assert!(!looks_like_pallet(&gap_cells(b, &rule), &rule), "record {} still striped", l.index);
            }
        }
        assert!(changed >= striped_before, "{changed} changed, {striped_before} striped");
        assert!(stderr(&o).contains(&format!("cleaned {changed}")), "{}", stderr(&o));
    }
}

#[test]
fn works_in_a_pipe_and_refuses_short_labels() {
    let o = run("dem-clean-pallet", &[], Some(std::fs::read(td("sim.npy")).unwrap()));
    let out = npy::NpyReader::new(ok(&o), "stdout", None).read_to_end().unwrap();
    assert_eq!(out.len(), 3025);
    let o = run("dem-clean-pallet", &["--labels", &td("real_labels.csv"), &td("sim.npy")], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("real_labels.csv"));
}
