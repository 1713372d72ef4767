//! The studies' command lines: one module per subcommand, each a clap struct
//! with a `run` method, and what only the studies write (figure strips, CSV
//! tables as JSON reports).

use std::path::Path;

use anyhow::Result;
use ifd_image::WriteOptions;

pub mod all;
pub mod isd_condition;
pub mod isd_convergence;
pub mod isd_mirror;
pub mod isd_visibility;
pub mod shrm;
pub mod zhf_sparsity;

/// The studies that stay scripts: name, what each regenerates, command.
pub const SCRIPTED: &[(&str, &str, &str)] = &[
    (
        "isd-table1",
        "ISD Table I: lobe-table memory and error against SH tables",
        "tests/bench/isd_table1.py",
    ),
    (
        "zhf-table2",
        "ZHF Table II: rotation cost against zxzxz and ducc0 (needs the Python venv)",
        "tests/bench/zhf_table2.py",
    ),
    (
        "ifd-decomposition-table",
        "IFD decomposition table: terms and errors per kernel",
        "crates/ifd-paper/scripts/decompose_report.py",
    ),
    (
        "ifd-vs-opencv",
        "IFD Figs. 3-4 against OpenCV: time against PSNR (needs the Python venv)",
        "tests/bench/curves_vs_opencv.py",
    ),
];

/// `ifd-paper list`: the studies of `cmd` (the binary's command tree), what
/// each regenerates, and the scripted ones with their commands.
pub fn list(cmd: &clap::Command) {
    println!("studies (ifd-paper NAME --help for each one's flags):");
    for sub in cmd
        .get_subcommands()
        .filter(|s| !matches!(s.get_name(), "list" | "all" | "help"))
    {
        println!(
            "  {:<18} {}",
            sub.get_name(),
            sub.get_about().map(ToString::to_string).unwrap_or_default()
        );
    }
    println!(
        "\n`ifd-paper all [--quick]` runs {} into one page each (docs/papers/NAME.md)",
        all::names().collect::<Vec<_>>().join(", ")
    );
    println!("\nscripted studies (run from the repository root):");
    for (name, what, script) in SCRIPTED {
        println!("  {name:<24} {what}\n  {:<24} {script}", "");
    }
}

/// Whether `path` is an 8-bit display format (PNG, JPEG, TIFF), which gets
/// the tone curve, rather than a float one.
pub fn is_display(path: &Path) -> Result<bool> {
    use ifd_image::FileFormat;
    Ok(matches!(
        FileFormat::from_path(path)?,
        FileFormat::Png | FileFormat::Jpeg | FileFormat::Tiff
    ))
}

/// The name of a direction sharing in reports (as `ifd sphere` spells it).
pub fn sharing_name(s: ifd_sphere::Sharing) -> &'static str {
    match s {
        ifd_sphere::Sharing::PerBand => "per-band",
        ifd_sphere::Sharing::Shared => "shared",
    }
}

/// Writes each named linear image into `dir` as `NAME.exr` and as
/// `NAME.png` (ACES tone curve at `exposure` stops, sRGB), then the PNGs side
/// by side, 4 white pixels apart, as `strip.png` (the figures of the
/// comparison studies). The images must share one size.
pub fn write_figure(dir: &Path, images: &[(&str, &ifd_image::Image)], exposure: f32) -> Result<()> {
    use crate::output::write_output;
    let tm = ifd_render::Tonemap::Aces;
    let opts = WriteOptions::default();
    let mut shown = Vec::new();
    for (name, im) in images {
        write_output(&dir.join(format!("{name}.exr")), im, &opts)?;
        let mut d = (*im).clone();
        for v in d.data_mut() {
            *v = tm.display(*v, exposure);
        }
        write_output(&dir.join(format!("{name}.png")), &d, &opts)?;
        shown.push(d);
    }
    let Some(first) = shown.first() else {
        return Ok(());
    };
    let (w, h, ch) = (first.width(), first.height(), first.channels());
    let gap = 4;
    let total = shown.len() * (w + gap) - gap;
    let mut strip = ifd_image::Image::from_vec(total, h, ch, vec![1.0; total * h * ch])?;
    for (i, d) in shown.iter().enumerate() {
        strip.paste(i * (w + gap), 0, d);
    }
    write_output(&dir.join("strip.png"), &strip, &opts)
}

/// A CSV table (header line, then rows) as a JSON report `{"rows": [...]}`,
/// one object per row, numbers as numbers.
#[must_use]
pub fn csv_report(csv: &str) -> serde_json::Value {
    use serde_json::Value;
    let mut lines = csv.lines();
    let header = csv_fields(lines.next().unwrap_or(""));
    let rows: Vec<Value> = lines
        .filter(|l| !l.is_empty())
        .map(|line| {
            let map = header
                .iter()
                .zip(csv_fields(line))
                .map(|(k, v)| {
                    let value = match v.parse::<f64>() {
                        Ok(x) if x.is_finite() => serde_json::json!(x),
                        _ if v == "true" || v == "false" => Value::Bool(v == "true"),
                        _ => Value::String(v),
                    };
                    (k.clone(), value)
                })
                .collect();
            Value::Object(map)
        })
        .collect();
    serde_json::json!({ "rows": rows })
}

/// The fields of one CSV line: commas inside double quotes do not split, the
/// quotes are dropped and `""` stands for one quote.
fn csv_fields(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' if quoted && chars.peek() == Some(&'"') => {
                chars.next();
                if let Some(f) = fields.last_mut() {
                    f.push('"');
                }
            }
            '"' => quoted = !quoted,
            ',' if !quoted => fields.push(String::new()),
            c => {
                if let Some(f) = fields.last_mut() {
                    f.push(c);
                }
            }
        }
    }
    fields
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_csv_table_becomes_rows_with_quoted_commas_kept() {
        let rows = csv_report("brdf,L\n\"ggx:ax=0.3,ay=0.6\",4\n\"a\"\"b\",5\n");
        assert_eq!(rows["rows"][0]["brdf"], "ggx:ax=0.3,ay=0.6");
        assert_eq!(rows["rows"][0]["L"], 4.0);
        assert_eq!(rows["rows"][1]["brdf"], "a\"b");
    }
}
