//! The command-line reference page (`docs/reference/cli.md`) from the
//! schemas.

use std::fmt::Write as _;

use serde_json::Value;

use crate::str_of;

/// The Markdown command-line reference of the given trees: a contents list,
/// then one section per command with its description and a table of its
/// arguments and flags.
#[must_use]
pub fn markdown(trees: &[&Value]) -> String {
    let mut out = String::from(
        "# Command-line reference\n\n\
         Generated from the binaries' definitions (`docs/reference/cli/*.json`); do not edit \
         by hand. To regenerate: `IFD_BLESS=1 cargo test -p ifd-cli -p ifd-brush -p \
         ifd-envrender -p ifd-paper --bins` (the schemas), then `IFD_BLESS=1 cargo test -p \
         ifd-clidoc` (this page). Every flag has one meaning across the four binaries \
         (checked by `ifd-clidoc`'s grammar test).\n\n",
    );
    let mut sections = Vec::new();
    for tree in trees {
        walk(tree, "", &mut sections);
    }
    for (path, _) in &sections {
        let depth = path.matches(' ').count();
        let _ = writeln!(out, "{}- [`{path}`](#{})", "  ".repeat(depth), anchor(path));
    }
    for (path, cmd) in &sections {
        let _ = write!(out, "\n## `{path}`\n\n");
        let about = cmd["long_about"]
            .as_str()
            .or(cmd["about"].as_str())
            .unwrap_or("");
        if !about.is_empty() {
            let _ = write!(out, "{}\n\n", about.trim());
        }
        let subs = cmd["subcommands"].as_array().map_or(0, Vec::len);
        let args = cmd["args"].as_array().map_or(&[][..], Vec::as_slice);
        let mut synopsis = path.clone();
        if subs > 0 {
            synopsis.push_str(" <COMMAND>");
        }
        for a in args.iter().filter(|a| a["positional"] == true) {
            let name = a["value_name"].as_str().unwrap_or(str_of(a, "id"));
            if a["required"] == true {
                let _ = write!(synopsis, " <{name}>");
            } else {
                let _ = write!(synopsis, " [{name}]");
            }
        }
        if args.iter().any(|a| a["positional"] != true) {
            synopsis.push_str(" [OPTIONS]");
        }
        let _ = write!(out, "```text\n{synopsis}\n```\n\n");
        if subs > 0 {
            out.push_str("| command | what it does |\n|---|---|\n");
            for sub in cmd["subcommands"].as_array().into_iter().flatten() {
                let sub_path = format!("{path} {}", str_of(sub, "name"));
                let _ = writeln!(
                    out,
                    "| [`{}`](#{}) | {} |",
                    str_of(sub, "name"),
                    anchor(&sub_path),
                    cell(sub["about"].as_str().unwrap_or(""))
                );
            }
            out.push('\n');
        }
        if !args.is_empty() {
            out.push_str("| argument | default | description |\n|---|---|---|\n");
            for a in args {
                let _ = writeln!(
                    out,
                    "| {} | {} | {} |",
                    arg_label(a),
                    a["default"]
                        .as_array()
                        .filter(|d| !d.is_empty())
                        .map(|d| {
                            let d: Vec<&str> = d.iter().filter_map(Value::as_str).collect();
                            format!("`{}`", d.join(","))
                        })
                        .unwrap_or_default(),
                    cell(&describe(a))
                );
            }
            out.push('\n');
        }
    }
    out
}

fn walk<'a>(cmd: &'a Value, prefix: &str, out: &mut Vec<(String, &'a Value)>) {
    let path = if prefix.is_empty() {
        str_of(cmd, "name").to_owned()
    } else {
        format!("{prefix} {}", str_of(cmd, "name"))
    };
    out.push((path.clone(), cmd));
    for sub in cmd["subcommands"].as_array().into_iter().flatten() {
        walk(sub, &path, out);
    }
}

fn anchor(path: &str) -> String {
    path.chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_ascii_alphanumeric() || c == '-' || c == '_' => Some(c.to_ascii_lowercase()),
            _ => None,
        })
        .collect()
}

fn arg_label(a: &Value) -> String {
    let value = a["value_name"].as_str().map(|v| format!(" <{v}>"));
    if a["positional"] == true {
        return format!(
            "`<{}>`",
            a["value_name"].as_str().unwrap_or(str_of(a, "id"))
        );
    }
    let mut label = String::new();
    if let Some(s) = a["short"].as_str() {
        let _ = write!(label, "`-{s}`, ");
    }
    let _ = write!(
        label,
        "`--{}{}`",
        str_of(a, "long"),
        value.unwrap_or_default()
    );
    label
}

fn describe(a: &Value) -> String {
    let mut text = a["help"].as_str().unwrap_or("").trim().to_owned();
    if let Some(values) = a["values"].as_array().filter(|v| !v.is_empty()) {
        let list: Vec<String> = values
            .iter()
            .map(|v| match v["help"].as_str() {
                Some(h) => format!("`{}` ({})", str_of(v, "name"), h.trim_end_matches('.')),
                None => format!("`{}`", str_of(v, "name")),
            })
            .collect();
        let _ = write!(text, " Values: {}.", list.join(", "));
    }
    if a["required"] == true {
        text.push_str(" Required.");
    }
    if a["repeatable"] == true {
        text.push_str(" Repeatable.");
    }
    text
}

/// A table cell: one line, pipes escaped.
fn cell(text: &str) -> String {
    text.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace('|', "\\|")
}
