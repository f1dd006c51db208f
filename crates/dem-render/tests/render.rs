//! dem-render run the way users run it: NPY files written here, the real
//! binary, the PNG decoded and its pixels checked where the layout promises.
//!
//! Positions are found from the picture itself (a 16 x 16 square of one
//! colour is one cell), so these tests check what a reader sees, not the
//! layout code's own arithmetic.

use std::path::Path;

use dem_core::format::{level_dem, Dem, DemCells};
use dem_core::npy;
use dem_testkit::{arg, ok, run, stderr, tempdir};

const CELL: usize = 16;
const DARK_RED: [u8; 3] = [128, 0, 0];
const DARK_BLUE: [u8; 3] = [0, 0, 128];
const WHITE: [u8; 3] = [255, 255, 255];

struct Image {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Image {
    fn decode(bytes: &[u8]) -> Image {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().expect("a PNG");
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).expect("PNG data");
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        buf.truncate(info.buffer_size());
        Image { width: info.width as usize, height: info.height as usize, rgb: buf }
    }

    fn open(path: &str) -> Image {
        Image::decode(&std::fs::read(path).expect("output PNG"))
    }

    fn px(&self, x: usize, y: usize) -> [u8; 3] {
        let i = (y * self.width + x) * 3;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    fn block_is(&self, x: usize, y: usize, c: [u8; 3]) -> bool {
        x + CELL <= self.width && y + CELL <= self.height && (0..CELL * CELL).all(|k| self.px(x + k % CELL, y + k / CELL) == c)
    }

    /// Top left corners of every cell-sized square of colour `c` that
    /// starts a run (nothing of `c` just above or left of it).
    fn cells_of(&self, c: [u8; 3]) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for y in 0..self.height {
            for x in 0..self.width {
                let starts = (x == 0 || self.px(x - 1, y) != c) && (y == 0 || self.px(x, y - 1) != c);
                if starts && self.block_is(x, y, c) {
                    out.push((x, y));
                }
            }
        }
        out
    }
}

fn write(dir: &Path, name: &str, recs: &[Dem]) -> String {
    let p = arg(dir, name);
    npy::write_all(&p, recs).unwrap();
    p
}

/// Record 0: max height at (0, 0), min at (19, 4), a missing cell (10, 2).
fn marked() -> Dem {
    let mut d = level_dem(0.1);
    d.set_valid(0, 0, 0.3);
    d.set_valid(19, 4, -0.1);
    d.set_missing(10, 2);
    d
}

fn size_from_log(err: &str) -> (usize, usize) {
    let dims = err.split(", ").nth(1).and_then(|s| s.strip_suffix(" px)\n")).expect(err);
    let (w, h) = dims.split_once('x').unwrap();
    (w.parse().unwrap(), h.parse().unwrap())
}

#[test]
fn grid_puts_row_0_at_the_top_max_dark_red_min_dark_blue_missing_white() {
    let dir = tempdir();
    let input = write(dir.path(), "d.npy", &[marked(), level_dem(0.1), level_dem(0.0)]);
    let out = arg(dir.path(), "grid.png");
    let res = run("dem-render", &[&input, "-o", &out], None);
    ok(&res);
    let err = stderr(&res);
    assert!(err.contains("wrote") && err.contains("(3 records"), "{err}");
    let img = Image::open(&out);
    assert_eq!((img.width, img.height), size_from_log(&err));
    // One band of 3 tiles of 80 x 320 px, text and a colour bar around them.
    assert!(img.width > 3 * 80 + 100 && img.width < 700, "{}", img.width);
    assert!(img.height > 320 + 32 && img.height < 480, "{}", img.height);

    let red = img.cells_of(DARK_RED);
    let blue = img.cells_of(DARK_BLUE);
    assert_eq!(red.len(), 1, "one cell at the max height: {red:?}");
    assert_eq!(blue.len(), 1, "one cell at the min height: {blue:?}");
    let ((xr, yr), (xb, yb)) = (red[0], blue[0]);
    // Cell (0, 0) top left, cell (19, 4) 19 rows down and 4 columns right.
    assert_eq!((xb - xr, yb - yr), (4 * CELL, 19 * CELL), "row 0 at the top, column 0 at the left");
    // Missing cell (10, 2) is white; its valid neighbours are not.
    assert!(img.block_is(xr + 2 * CELL, yr + 10 * CELL, WHITE));
    assert_ne!(img.px(xr + 2 * CELL + 8, yr + 9 * CELL + 8), WHITE);
    assert_ne!(img.px(xr + 3 * CELL + 8, yr + 10 * CELL + 8), WHITE);
    // A black frame just outside the tile and the index label above it.
    assert_eq!(img.px(xr - 1, yr - 1), [0, 0, 0]);
    let label = (yr.saturating_sub(30)..yr - 2).any(|y| (xr..xr + 5 * CELL).any(|x| img.px(x, y)[0] < 100));
    assert!(label, "no index text above the first tile");
}

#[test]
fn fixed_range_colours_heights_against_vmin_vmax() {
    let dir = tempdir();
    let mut d = level_dem(0.0);
    d.set_valid(3, 1, 1.0);
    d.set_valid(4, 1, -1.0);
    let input = write(dir.path(), "d.npy", &[d]);
    let out = arg(dir.path(), "r.png");
    ok(&run("dem-render", &[&input, "--vmin", "-1", "--vmax=1", "-o", &out], None));
    let img = Image::open(&out);
    let (red, blue) = (img.cells_of(DARK_RED), img.cells_of(DARK_BLUE));
    assert_eq!((red.len(), blue.len()), (1, 1));
    assert_eq!((blue[0].0, blue[0].1 - red[0].1), (red[0].0, CELL));
    // Height 0 sits mid-range: matplotlib's jet(0.5) = (0.490, 1.0, 0.478).
    assert_eq!(img.px(red[0].0 + 8, red[0].1 - CELL + 8), [125, 255, 122]);
}

#[test]
fn indices_are_drawn_in_the_order_given() {
    let dir = tempdir();
    let mut hi = level_dem(0.0);
    hi.set_valid(0, 0, 0.5);
    let mut lo = level_dem(0.0);
    lo.set_valid(0, 0, -0.5);
    let input = write(dir.path(), "d.npy", &[lo, level_dem(0.0), hi]);
    let out = arg(dir.path(), "i.png");
    ok(&run("dem-render", &[&input, "--indices", "2,0", "-o", &out], None));
    let img = Image::open(&out);
    let (red, blue) = (img.cells_of(DARK_RED), img.cells_of(DARK_BLUE));
    assert_eq!((red.len(), blue.len()), (1, 1));
    assert!(red[0].0 < blue[0].0, "record 2 (dark red) must come first: {red:?} {blue:?}");
    // The same through an index CSV.
    let csv = arg(dir.path(), "keep.csv");
    std::fs::write(&csv, "index,why\n0,low\n2,high\n").unwrap();
    ok(&run("dem-render", &[&input, "--index", &csv, "-o", &out], None));
    let img = Image::open(&out);
    assert!(img.cells_of(DARK_BLUE)[0].0 < img.cells_of(DARK_RED)[0].0);
}

#[test]
fn compare_stacks_three_files_as_rows_with_errors_under_columns() {
    let dir = tempdir();
    let files: Vec<String> = ["in", "real", "gen"]
        .iter()
        .map(|name| write(dir.path(), &format!("{name}.npy"), &[marked(), level_dem(0.1), level_dem(0.0), level_dem(0.0)]))
        .collect();
    let one = arg(dir.path(), "one.png");
    ok(&run("dem-render", &[&files[0], "--count", "2", "-o", &one], None));
    let out = arg(dir.path(), "cmp.png");
    let mut args = vec!["--compare"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--row-labels", "input,closest real,generated", "--error-rows", "2,3", "--count", "2", "-o", &out]);
    let res = run("dem-render", &args, None);
    ok(&res);
    assert!(stderr(&res).contains("3 files x 2 records"), "{}", stderr(&res));
    let (img, single) = (Image::open(&out), Image::open(&one));
    // Three tile rows where the grid has one: at least two more tiles high.
    assert!(img.height >= single.height + 2 * 320, "{} vs {}", img.height, single.height);
    // Record 0's max cell once per file, same column, one tile row apart.
    let red = img.cells_of(DARK_RED);
    assert_eq!(red.len(), 3, "{red:?}");
    assert!(red.iter().all(|p| p.0 == red[0].0));
    let pitch = red[1].1 - red[0].1;
    assert!(pitch > 320 && pitch < 360 && red[2].1 - red[1].1 == pitch, "{red:?}");
    // Row labels take room on the left; the error line is under the last row.
    assert!(red[0].0 > 150, "row labels left of the tiles: {red:?}");
    let last_bottom = red[2].1 + 20 * CELL;
    let caption = (last_bottom + 2..img.height).any(|y| (red[0].0..red[0].0 + 80).any(|x| img.px(x, y)[0] < 100));
    assert!(caption, "no error caption under the first column");
}

#[test]
fn png_to_stdout_from_stdin() {
    let dir = tempdir();
    let input = write(dir.path(), "d.npy", &[marked()]);
    let bytes = std::fs::read(&input).unwrap();
    let res = run("dem-render", &["-", "-o", "-"], Some(bytes.clone()));
    let png = ok(&res);
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"));
    let img = Image::decode(png);
    assert_eq!(img.cells_of(DARK_RED).len(), 1);
    assert!(stderr(&res).contains("PNG to stdout"));
    // No INPUT means stdin too.
    let res = run("dem-render", &["-o", "-"], Some(bytes));
    assert_eq!(Image::decode(ok(&res)).width, img.width);
}

/// Run, expect exit 2 with one error line containing every `needles`, and
/// no output (nor a temp file) left in `dir`.
#[test]
fn per_terrain_draws_evenly_spaced_records_of_each_terrain_in_terrain_order() {
    let dir = tempdir();
    // Nine records: terrains p f s p f p u p f (pallet, flat, stairs-down, stairs-up).
    let terrains = ["pallet", "flat", "stairs-down", "pallet", "flat", "pallet", "stairs-up", "pallet", "flat"];
    let recs: Vec<Dem> = (0..9).map(|k| level_dem(k as f32 / 10.0)).collect();
    let input = write(dir.path(), "d.npy", &recs);
    let labels = arg(dir.path(), "l.csv");
    let rows: String = terrains.iter().enumerate().map(|(i, t)| format!("{i},{t}\n")).collect();
    std::fs::write(&labels, format!("index,terrain\n{rows}")).unwrap();
    // K = 2: flat (1, 4, 8) -> places 1, 2 of 3 -> records 4, 8; stairs-up
    // (6) -> 6 once; stairs-down (2) -> 2 once; pallet (0, 3, 5, 7) -> places 1, 2 -> 3, 5.
    let (a, b) = (arg(dir.path(), "a.png"), arg(dir.path(), "b.png"));
    ok(&run("dem-render", &[&input, "--per-terrain", "2", "--labels", &labels, "-o", &a], None));
    ok(&run("dem-render", &[&input, "--indices", "4,8,6,2,3,5", "-o", &b], None));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "the same picture as the indices it picks");
    // dem-eval's records file works too: the terrain column is found by name.
    let records = arg(dir.path(), "r.csv");
    let rows: String = terrains.iter().enumerate().map(|(i, t)| format!("{i},7,0.5,{t},1.0\n")).collect();
    std::fs::write(&records, format!("sim_index,real_index,error,terrain,height_cm\n{rows}")).unwrap();
    ok(&run("dem-render", &[&input, "--per-terrain", "2", "--labels", &records, "-o", &a], None));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    // No terrain column, an unknown terrain: exit 2 naming the file and line.
    std::fs::write(&records, "index,kind\n0,flat\n").unwrap();
    refused(
        dir.path(),
        &[&input, "--per-terrain", "2", "--labels", &records, "-o", &arg(dir.path(), "x.png")],
        &["r.csv", "no terrain column"],
    );
    std::fs::write(&records, "index,terrain\n0,flat\n1,moon\n").unwrap();
    refused(dir.path(), &[&input, "--per-terrain", "2", "--labels", &records, "-o", &arg(dir.path(), "x.png")], &["r.csv", "line 3"]);
}

fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let before: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    let res = run("dem-render", args, None);
    let err = stderr(&res);
    assert_eq!(res.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: {err:?} lacks {n:?}");
    }
    let after: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(before, after, "{args:?} left files behind");
}

#[test]
fn bad_inputs_exit_2_naming_the_file_and_leave_no_output() {
    let dir = tempdir();
    let d = dir.path();
    let good = write(d, "good.npy", &[level_dem(0.0); 4]);
    let five = write(d, "five.npy", &[level_dem(0.0); 5]);
    let bytes = std::fs::read(&good).unwrap();
    let cut = arg(d, "cut.npy");
    std::fs::write(&cut, &bytes[..bytes.len() - 100]).unwrap();
    let out = arg(d, "out.png");
    let missing = arg(d, "nope.npy");
    refused(d, &[&missing, "-o", &out], &["nope.npy", "failed to open"]);
    refused(d, &[&cut, "-o", &out], &["cut.npy", "3260 bytes"]);
    refused(d, &[&good, "--indices", "1,7", "-o", &out], &["good.npy", "record 7", "4 records"]);
    refused(d, &[&good, "--start", "4", "-o", &out], &["good.npy", "--start 4"]);
    // Files of different lengths: an index past the shorter one's end is refused ...
    refused(d, &["--compare", &five, &good, "--indices", "4", "-o", &out], &["good.npy", "4"]);
    refused(d, &["--compare", &good, &cut, "-o", &out], &["cut.npy"]);
    let csv = arg(d, "c.csv");
    std::fs::write(&csv, "index,error\n0,0.5\n").unwrap();
    refused(d, &[&good, "--count", "2", "--captions", &csv, "-o", &out], &["c.csv", "record 1"]);
    refused(d, &[&good, "--captions", &csv, "--caption-column", "e", "-o", &out], &["c.csv", "\"e\""]);
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempdir();
    let d = dir.path();
    let good = write(d, "good.npy", &[level_dem(0.0); 4]);
    let out = arg(d, "out.png");
    refused(d, &[&good, "--count", "401", "-o", &out], &["at most 400"]);
    refused(d, &[&good, &good, "-o", &out], &["--compare"]);
    refused(d, &["--compare", &good, &good, "--error-rows", "1,3", "-o", &out], &["row 3"]);
    refused(d, &["--compare", &good, &good, "--error-rows", "1", "-o", &out], &["R,P"]);
    refused(d, &["--compare", &good, &good, "--row-labels", "a,b,c", "-o", &out], &["3 row labels"]);
    refused(d, &[&good, "--vmin", "1", "--vmax", "0", "-o", &out], &["--vmin 1"]);
    refused(d, &[&good, "-o", &good], &["overwrite"]);
    // clap's own refusals also exit 2 (several lines: usage and hint).
    let res = run("dem-render", &[&good, "--start", "1", "--indices", "2", "-o", &out], None);
    assert_eq!(res.status.code(), Some(2));
    assert!(!Path::new(&out).exists());
}

#[test]
fn captions_from_a_csv_and_the_help_example() {
    let dir = tempdir();
    let d = dir.path();
    let good = write(d, "good.npy", &[level_dem(0.0), level_dem(0.1)]);
    let csv = arg(d, "c.csv");
    std::fs::write(&csv, "sim_index,real_index,distance\n0,0,0.25\n1,1,0.5\n").unwrap();
    let with = arg(d, "with.png");
    let without = arg(d, "without.png");
    ok(&run("dem-render", &[&good, "--columns", "1", "--captions", &csv, "-o", &with], None));
    ok(&run("dem-render", &[&good, "--columns", "1", "-o", &without], None));
    // A caption line under each of the two bands makes the picture taller.
    assert!(Image::open(&with).height > Image::open(&without).height);
    let help = String::from_utf8_lossy(ok(&run("dem-render", &["--help"], None))).into_owned();
    assert!(help.contains("dem-render --compare") && help.contains("--error-rows"), "{help}");
}

#[test]
fn compare_draws_a_range_every_file_holds_and_refuses_one_past_a_shorter_file() {
    let dir = tempdir();
    let d = dir.path();
    let four = write(d, "four.npy", &[level_dem(0.0); 4]);
    let six = write(d, "six.npy", &[level_dem(0.0); 6]);
    let out = arg(d, "out.png");
    // Files of unequal length: a range inside both is drawn whole ...
    let res = run("dem-render", &["--compare", &six, &four, "--start", "1", "--count", "3", "-o", &out], None);
    ok(&res);
    assert!(stderr(&res).contains("2 files x 3 records"), "{}", stderr(&res));
    std::fs::remove_file(&out).unwrap();
    // ... one past the shorter file's end is refused, naming both files and
    // their lengths, where it once drew fewer records than asked.
    let res = run("dem-render", &["--compare", &six, &four, "--start", "1", "--count", "5", "-o", &out], None);
    assert_eq!(res.status.code(), Some(2), "{}", stderr(&res));
    let e = stderr(&res);
    assert!(e.lines().count() == 1 && e.contains("four.npy holds 4 records") && e.contains("six.npy holds 6"), "{e}");
    assert!(e.contains("--start 1 --count 5"), "{e}");
    assert!(!Path::new(&out).exists());
    // Files of equal length: a range past their end is cut, as for one file.
    let res = run("dem-render", &["--compare", &four, &four, "--start", "2", "--count", "5", "-o", &out], None);
    ok(&res);
    assert!(stderr(&res).contains("2 files x 2 records"), "{}", stderr(&res));
}
