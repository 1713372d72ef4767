//! The checked-in schemas (`docs/reference/cli/<bin>.json`): each binary
//! against its file, with a readable diff, or rewritten under `IFD_BLESS=1`.

use std::path::{Path, PathBuf};

use clap::Command;
use serde_json::Value;

use crate::EXCEPTIONS;
use crate::grammar::check_grammar;
use crate::schema::schema;
use crate::str_of;

/// The test each binary runs on its own command line: the tree follows the
/// grammar on its own, and equals the checked-in
/// `docs/reference/cli/<name>.json` (`name` is the command's; with
/// `IFD_BLESS=1` the file is rewritten instead, as by [`check_file`]).
///
/// # Errors
/// The grammar problems, or how the file differs.
pub fn check_binary(cmd: Command) -> Result<(), String> {
    let path = reference_dir()
        .join("cli")
        .join(format!("{}.json", cmd.get_name()));
    let schema = schema(cmd);
    let problems = check_grammar(&[&schema], EXCEPTIONS);
    if !problems.is_empty() {
        return Err(problems.join("\n"));
    }
    check_file(&schema, &path)
}

/// `docs/reference/` of the workspace.
pub(crate) fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/reference")
}

/// Compares `schema` with the checked-in JSON at `path`; with `IFD_BLESS=1`
/// in the environment, (re)writes the file instead. The error says how to
/// regenerate it and which commands differ.
///
/// # Errors
/// The file is missing, unreadable or differs from `schema`.
pub fn check_file(schema: &Value, path: &Path) -> Result<(), String> {
    compare_or_bless(
        schema,
        path,
        std::env::var_os("IFD_BLESS").is_some_and(|v| v == "1"),
    )
}

pub(crate) fn compare_or_bless(schema: &Value, path: &Path, bless: bool) -> Result<(), String> {
    let text = format!(
        "{}\n",
        serde_json::to_string_pretty(schema).map_err(|e| e.to_string())?
    );
    if bless {
        return std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()));
    }
    let old = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if old == text {
        return Ok(());
    }
    let mut differ = Vec::new();
    if let Ok(old) = serde_json::from_str::<Value>(&old) {
        diff_commands(&old, schema, "", &mut differ);
    }
    Err(format!(
        "{} is not what the binary defines (commands that differ: {}); if the change is meant, \
         regenerate it with IFD_BLESS=1 and the same test, then docs/reference/cli.md with \
         IFD_BLESS=1 cargo test -p ifd-clidoc",
        path.display(),
        if differ.is_empty() {
            "formatting only".to_owned()
        } else {
            differ.join(", ")
        }
    ))
}

fn diff_commands(old: &Value, new: &Value, prefix: &str, out: &mut Vec<String>) {
    let path = format!("{prefix}{}", str_of(new, "name"));
    let shallow = |v: &Value| {
        let mut v = v.clone();
        v["subcommands"] = Value::Null;
        v
    };
    if shallow(old) != shallow(new) {
        out.push(path.clone());
    }
    let empty = Vec::new();
    let olds = old["subcommands"].as_array().unwrap_or(&empty);
    for sub in new["subcommands"].as_array().unwrap_or(&empty) {
        match olds.iter().find(|o| o["name"] == sub["name"]) {
            Some(o) => diff_commands(o, sub, &format!("{path} "), out),
            None => out.push(format!("{path} {} (new)", str_of(sub, "name"))),
        }
    }
    for o in olds {
        if !new["subcommands"]
            .as_array()
            .is_some_and(|n| n.iter().any(|s| s["name"] == o["name"]))
        {
            out.push(format!("{path} {} (removed)", str_of(o, "name")));
        }
    }
}
