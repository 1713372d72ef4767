//! The `ifd-paper` binary's command line: every study runs at small sizes
//! and leaves its page (`ifd-paper all --quick`, what CI runs of the
//! studies), `ifd-paper list` names them, and bad parameters are refused.

use std::path::Path;
use std::process::Command;

/// Runs `cmd` and returns its exit code (-1 when killed), stdout and stderr.
fn run(cmd: &mut Command) -> (i32, String, String) {
    let out = cmd.output().expect("run ifd-paper");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The `ifd-paper` binary under test.
fn paper_command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ifd-paper"))
}

/// Runs `ifd-paper ARGS...`.
fn paper(args: &[&str]) -> (i32, String, String) {
    run(paper_command().args(args))
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

#[test]
fn isd_condition_refuses_a_degree_past_the_dense_limit() {
    for lmax in ["0", "41"] {
        let (code, _, err) = paper(&["isd-condition", "--lmax", lmax]);
        assert_eq!(code, 2);
        assert!(err.contains("--lmax") && err.contains("1..=40"), "{err}");
    }
}

#[test]
fn condition_marks_singular_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, out, err) = paper(&[
        "isd-condition",
        "--json",
        "--lmax",
        "8",
        "--csv",
        &p(d, "c.csv"),
        "--plot",
        &p(d, "c.png"),
    ]);
    assert_eq!(code, 0, "{err}");
    let rows: Vec<serde_json::Value> = serde_json::from_str(out.trim()).unwrap();
    let csv = std::fs::read_to_string(p(d, "c.csv")).unwrap();
    assert!(csv.starts_with("L,profile,sharing,cond,singular\n"));
    let mut singular = 0;
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let cond: f64 = f[3].parse().unwrap();
        assert_eq!(f[4] == "true", !cond.is_finite() || cond >= 1e16, "{line}");
        singular += usize::from(f[4] == "true");
        // the JSON has null exactly where the CSV says singular
        let l: usize = f[0].parse().unwrap();
        let r = rows
            .iter()
            .find(|r| r["profile"] == f[1] && r["sharing"] == f[2])
            .unwrap();
        assert_eq!(r["cond"][l - 1].is_null(), f[4] == "true", "{line}");
    }
    // Phong with shared directions loses odd bands (ISD Fig. 13): singular
    assert!(singular > 0, "{csv}");
    let png = ifd_image::read(p(d, "c.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1000, 640));
}

#[test]
fn list_names_every_study() {
    let (code, out, err) = paper(&["list"]);
    assert_eq!(code, 0, "{err}");
    for name in STUDIES.iter().chain(&["tests/bench/zhf_table2.py"]) {
        assert!(out.contains(name), "{name}: {out}");
    }
}

/// The studies of `ifd-paper`.
const STUDIES: [&str; 7] = [
    "isd-convergence",
    "isd-condition",
    "isd-mirror",
    "isd-visibility",
    "shrm-table4",
    "shrm-table5",
    "zhf-sparsity",
];

/// `ifd-paper all --quick` (what CI runs of the studies): every study runs at
/// small sizes and leaves its page, with the paper's account, the command and
/// the report, and its figures.
#[test]
fn all_quick_writes_every_page() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = run(paper_command()
        .current_dir(&root)
        .args(["all", "--quick", "--out-dir"])
        .arg(dir.path()));
    assert_eq!(out.0, 0, "{}", out.2);
    let (_, list, _) = paper(&["list"]);
    for name in STUDIES {
        let page = std::fs::read_to_string(dir.path().join(format!("{name}.md")))
            .unwrap_or_else(|e| panic!("{name}.md: {e}"));
        assert!(page.contains("## What the paper reports"), "{name}: {page}");
        assert!(
            page.contains(&format!("ifd-paper {name} ")),
            "{name}: {page}"
        );
        assert!(
            list.contains(name),
            "{name} not in `ifd-paper list`: {list}"
        );
    }
    // figures are written and linked
    assert!(dir.path().join("isd-condition/cond.png").is_file());
    let cond = std::fs::read_to_string(dir.path().join("isd-condition.md")).unwrap();
    assert!(cond.contains("](isd-condition/cond.png)"), "{cond}");
    // the paper's numbers sit beside ours where the paper gives numbers
    let t5 = std::fs::read_to_string(dir.path().join("shrm-table5.md")).unwrap();
    assert!(
        t5.contains("| sigma |") && t5.contains("paper ratio"),
        "{t5}"
    );
    // a quick run is not written over the documentation's pages
    let (code, _, err) = paper(&["all", "--quick"]);
    assert_eq!(code, 2);
    assert!(err.contains("--out-dir"), "{err}");
    // a name that is not a study is refused with the list
    let (code, _, err) = paper(&["all", "--only", "nope"]);
    assert_eq!(code, 2);
    assert!(err.contains("isd-mirror"), "{err}");
}
