//! Dictionary study: relative L2 error versus number of terms for several `MoG`
//! dictionary choices, on the accuracy-target filters.
//!
//! ```text
//! cargo run --release -p ifd-paper --example dictionary_study -- study docs/dictionary-study.csv
//! cargo run --release -p ifd-paper --example dictionary_study -- one gauss:sx=24,sy=3,theta=30 ratio=0.5 spo=4 over=1 dlevels=0 gap=0.01 tol=0.01
//! ```
//!
//! `study` varies one parameter at a time around the defaults (sigma/spacing
//! ratio, number of levels relative to the automatic choice, grid
//! oversampling, sigmas per octave) and, for each, fits every filter at a
//! ladder of target errors, writing one CSV row per fit.

use std::fmt::Write as _;
use std::io::Write as _;

use ifd_planar::internals::dictionary::{DictionaryOptions, DictionaryParams};
use ifd_planar::{DecomposeOptions, Kernel, decompose};

struct Config {
    name: String,
    ratio: f64,
    dlevels: i64,
    over: usize,
    spo: usize,
}

fn options(
    c: &Config,
    kernel: &Kernel,
    tol: f64,
    gap: f64,
) -> Result<DecomposeOptions, Box<dyn std::error::Error>> {
    let mut dict = DictionaryOptions {
        ratio: c.ratio,
        sigmas_per_octave: c.spo,
        oversampling: c.over,
        ..DictionaryOptions::default()
    };
    let auto = DictionaryParams::for_kernel(kernel, &dict)?.levels as i64;
    dict.levels = Some((auto + c.dlevels).max(1) as usize);
    Ok(DecomposeOptions {
        tol,
        dictionary: dict,
        stage_gap: gap,
        extra_stages: std::env::var("IFD_EXTRA")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(1),
        ..DecomposeOptions::default()
    })
}

fn run(spec: &str, c: &Config, tol: f64, gap: f64) -> Result<String, Box<dyn std::error::Error>> {
    let kernel: Kernel = spec.parse()?;
    let opts = options(c, &kernel, tol, gap)?;
    let d = decompose(&kernel, &opts, |_, _, _| {})?;
    let r = d.report.as_ref().ok_or("no report")?;
    let p = d.dictionary.as_ref().ok_or("no dictionary")?;
    Ok(format!(
        "\"{}\",\"{}\",{},{},{},{},{},{},{:.3},{},{:.6},{:.6},{:.3e},{},{:.3}",
        c.name,
        spec,
        c.ratio,
        p.levels,
        c.over,
        c.spo,
        tol,
        r.dictionary_atoms,
        p.finest_sigma(),
        r.terms,
        r.rel_l2_error,
        r.max_error,
        r.dc_error,
        r.iterations,
        r.seconds
    ))
}

const HEADER: &str = "config,filter,ratio,levels,oversampling,sigmas_per_octave,tol,atoms,finest_sigma,terms,rel_l2_error,max_error,dc_error,iterations,seconds";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map_or("study", String::as_str);
    if mode == "one" {
        let spec = args.get(1).ok_or("usage: one SPEC [key=value...]")?;
        let mut c = Config {
            name: "one".into(),
            ratio: 0.5,
            dlevels: 0,
            over: 1,
            spo: 4,
        };
        let (mut gap, mut tol) = (0.1, 0.01);
        for kv in &args[2..] {
            let (k, v) = kv.split_once('=').ok_or("key=value")?;
            match k {
                "ratio" => c.ratio = v.parse()?,
                "dlevels" => c.dlevels = v.parse()?,
                "over" => c.over = v.parse()?,
                "spo" => c.spo = v.parse()?,
                "gap" => gap = v.parse()?,
                "tol" => tol = v.parse()?,
                _ => return Err(format!("unknown key {k}").into()),
            }
        }
        println!("{HEADER}");
        println!("{}", run(spec, &c, tol, gap)?);
        return Ok(());
    }
    let out = args.get(1).map_or("dictionary-study.csv", String::as_str);
    let base = |name: &str| Config {
        name: name.into(),
        ratio: 0.5,
        dlevels: 0,
        over: 1,
        spo: 4,
    };
    let mut configs = vec![base("default")];
    for r in [0.35, 0.7, 1.0] {
        configs.push(Config {
            ratio: r,
            ..base(&format!("ratio={r}"))
        });
    }
    for dl in [-1, 1] {
        configs.push(Config {
            dlevels: dl,
            ..base(&format!("levels{dl:+}"))
        });
    }
    configs.push(Config {
        over: 2,
        ..base("oversampling=2")
    });
    for spo in [1, 2] {
        configs.push(Config {
            spo,
            ..base(&format!("sigmas_per_octave={spo}"))
        });
    }
    configs.push(Config {
        spo: 1,
        ratio: 0.7,
        ..base("spo=1 ratio=0.7 (probe)")
    });
    let filters = [
        "gauss:sx=12,sy=3,theta=30",
        "gauss:sx=24,sy=3,theta=30",
        "dgauss:order=xx,sigma=4",
    ];
    let tols = [0.04, 0.02, 0.01, 0.005, 0.0025];
    let mut csv = String::from(HEADER);
    csv.push('\n');
    for c in &configs {
        for f in filters {
            for tol in tols {
                let line = run(f, c, tol, 0.1)?;
                eprintln!("{line}");
                let _ = writeln!(csv, "{line}");
            }
        }
    }
    std::fs::File::create(out)?.write_all(csv.as_bytes())?;
    eprintln!("wrote {out}");
    Ok(())
}
