//! The command lines of `ifd`, `ifd-brush` and `ifd-envrender` as data.
//!
//! Three jobs, one representation:
//!
//! - [`schema`] turns a clap command tree into JSON: every subcommand, and for
//!   every flag its long and short names, value name, value *kind* (path,
//!   string, integer, number, enum with its values, flag, count), default and
//!   help. Each binary checks its schema into `docs/reference/cli/<bin>.json`
//!   and a test compares it with what the binary defines ([`check_file`]), so
//!   a change to a command line is deliberate and visible in review.
//! - [`check_grammar`] checks the rules that make the three binaries read as
//!   one tool (`../shared/STYLE.md`, "Command-line grammar"): a flag name has
//!   one kind and one value shape everywhere, `-o/--output` is always a file,
//!   a folder is always a `--*-dir` flag, `--size` is always `WxH`, `--json`
//!   is always a switch, and a value with a fixed set of choices is an enum
//!   (listed by `--help`, a wrong one refused with the list).
//! - [`markdown`] writes the command-line reference (`docs/reference/cli.md`).
//!
//! ```
//! use clap::{Arg, ArgAction, Command};
//! let cmd = Command::new("demo").subcommand(
//!     Command::new("run")
//!         .arg(Arg::new("output").long("output").short('o').value_name("FILE")
//!             .help("Output file.")
//!             .value_parser(clap::value_parser!(std::path::PathBuf)))
//!         .arg(Arg::new("json").long("json").help("JSON report.").action(ArgAction::SetTrue)),
//! );
//! let s = ifd_clidoc::schema(cmd);
//! assert!(ifd_clidoc::check_grammar(&[&s], &[]).is_empty());
//! assert!(ifd_clidoc::markdown(&[&s]).contains("`-o`, `--output <FILE>`"));
//! ```

use std::any::TypeId;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::{Arg, ArgAction, Command};
use serde_json::{Value, json};

/// The JSON schema of a command tree (hidden commands and flags left out:
/// they are old spellings kept only to be refused with a message).
#[must_use]
pub fn schema(mut cmd: Command) -> Value {
    cmd.build();
    command_schema(&cmd)
}

fn command_schema(cmd: &Command) -> Value {
    let args: Vec<Value> = cmd
        .get_arguments()
        .filter(|a| !a.is_hide_set() && !matches!(a.get_id().as_str(), "help" | "version"))
        .map(arg_schema)
        .collect();
    let subcommands: Vec<Value> = cmd
        .get_subcommands()
        .filter(|c| !c.is_hide_set() && c.get_name() != "help")
        .map(command_schema)
        .collect();
    json!({
        "name": cmd.get_name(),
        "about": cmd.get_about().map(ToString::to_string),
        "long_about": cmd.get_long_about().map(ToString::to_string),
        "args": args,
        "subcommands": subcommands,
    })
}

/// The kind of value a flag takes, from its action and value parser.
fn kind(arg: &Arg) -> &'static str {
    match arg.get_action() {
        ArgAction::SetTrue | ArgAction::SetFalse => return "switch",
        ArgAction::Count => return "count",
        _ => {}
    }
    if arg.get_possible_values().iter().any(|v| !v.is_hide_set()) {
        return "enum";
    }
    let t = arg.get_value_parser().type_id();
    let is = |id: TypeId| t == id;
    if is(TypeId::of::<PathBuf>()) {
        "path"
    } else if is(TypeId::of::<String>()) {
        "string"
    } else if [
        TypeId::of::<u8>(),
        TypeId::of::<u16>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
    ]
    .into_iter()
    .any(is)
    {
        "unsigned"
    } else if [
        TypeId::of::<i8>(),
        TypeId::of::<i16>(),
        TypeId::of::<i32>(),
        TypeId::of::<i64>(),
    ]
    .into_iter()
    .any(is)
    {
        "integer"
    } else if is(TypeId::of::<f32>()) || is(TypeId::of::<f64>()) {
        "number"
    } else {
        "other"
    }
}

fn arg_schema(arg: &Arg) -> Value {
    let kind = kind(arg);
    let values: Vec<Value> = if kind == "enum" {
        arg.get_possible_values()
            .iter()
            .filter(|v| !v.is_hide_set())
            .map(|v| json!({"name": v.get_name(), "help": v.get_help().map(ToString::to_string)}))
            .collect()
    } else {
        Vec::new()
    };
    let value_name = arg
        .get_value_names()
        .map(|names| {
            names
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(" ")
        })
        .filter(|_| !matches!(kind, "switch" | "count"));
    let default: Vec<String> = arg
        .get_default_values()
        .iter()
        .map(|v| v.to_string_lossy().into_owned())
        .filter(|_| !matches!(kind, "switch" | "count"))
        .collect();
    json!({
        "id": arg.get_id().as_str(),
        "positional": arg.is_positional(),
        "long": arg.get_long(),
        "short": arg.get_short().map(String::from),
        "value_name": value_name,
        "kind": kind,
        "values": values,
        "default": default,
        "required": arg.is_required_set(),
        "repeatable": matches!(arg.get_action(), ArgAction::Append),
        "help": arg.get_long_help().or(arg.get_help()).map(ToString::to_string),
    })
}

/// One use of a flag: the command path (`ifd sphere sh`) and the flag's schema.
struct Use<'a> {
    command: String,
    arg: &'a Value,
}

fn collect<'a>(cmd: &'a Value, prefix: &str, out: &mut Vec<Use<'a>>) {
    let name = cmd["name"].as_str().unwrap_or("?");
    let path = if prefix.is_empty() {
        name.to_owned()
    } else {
        format!("{prefix} {name}")
    };
    for arg in cmd["args"].as_array().into_iter().flatten() {
        out.push(Use {
            command: path.clone(),
            arg,
        });
    }
    for sub in cmd["subcommands"].as_array().into_iter().flatten() {
        collect(sub, &path, out);
    }
}

/// A flag allowed to break the one-meaning rule, with the reason.
#[derive(Debug, Clone, Copy)]
pub struct Exception {
    /// The long flag name, without dashes.
    pub long: &'static str,
    /// Why the flag means different things in different commands.
    pub reason: &'static str,
}

/// The flags allowed several shapes across the three binaries: none.
pub const EXCEPTIONS: &[Exception] = &[];

/// The binaries whose schemas are checked in under `docs/reference/cli/`.
pub const BINARIES: [&str; 3] = ["ifd", "ifd-brush", "ifd-envrender"];

fn str_of<'a>(v: &'a Value, key: &str) -> &'a str {
    v[key].as_str().unwrap_or("")
}

/// Every breach of the grammar in the given command trees, one sentence each
/// (empty when they read as one tool). Flags in `exceptions` may have several
/// shapes; every other rule still applies to them.
#[must_use]
pub fn check_grammar(trees: &[&Value], exceptions: &[Exception]) -> Vec<String> {
    let mut uses = Vec::new();
    for tree in trees {
        collect(tree, "", &mut uses);
    }
    let mut problems = Vec::new();
    // one kind and one value shape per long name, one long name per short letter
    let mut shapes: BTreeMap<&str, BTreeMap<String, Vec<&str>>> = BTreeMap::new();
    let mut shorts: BTreeMap<&str, BTreeMap<&str, Vec<&str>>> = BTreeMap::new();
    for u in &uses {
        let Some(long) = u.arg["long"].as_str() else {
            continue;
        };
        // a path's value name only hints at its format (FILE, IMAGE, NPY):
        // its shape is whether it names a file or a folder
        let value_name = u.arg["value_name"].as_str().unwrap_or("-");
        let shape = match str_of(u.arg, "kind") {
            "path" if value_name == "DIR" => "folder".to_owned(),
            "path" => "file".to_owned(),
            kind => format!("{kind} {value_name}"),
        };
        shapes
            .entry(long)
            .or_default()
            .entry(shape)
            .or_default()
            .push(&u.command);
        if let Some(short) = u.arg["short"].as_str() {
            shorts
                .entry(short)
                .or_default()
                .entry(long)
                .or_default()
                .push(&u.command);
        }
    }
    for (long, by_shape) in &shapes {
        if by_shape.len() > 1 && !exceptions.iter().any(|e| e.long == *long) {
            let list: Vec<String> = by_shape
                .iter()
                .map(|(shape, cmds)| format!("{shape} in {}", cmds.join(", ")))
                .collect();
            problems.push(format!(
                "--{long} has {} shapes (kind and value name): {}",
                by_shape.len(),
                list.join("; ")
            ));
        }
    }
    for (short, by_long) in &shorts {
        if by_long.len() > 1 {
            let list: Vec<String> = by_long
                .iter()
                .map(|(long, cmds)| format!("--{long} in {}", cmds.join(", ")))
                .collect();
            problems.push(format!(
                "-{short} stands for several flags: {}",
                list.join("; ")
            ));
        }
        if *short == "o" && by_long.keys().any(|l| *l != "output") {
            problems.push("-o is only ever short for --output".to_owned());
        }
    }
    for u in &uses {
        let Some(long) = u.arg["long"].as_str() else {
            continue;
        };
        let kind = str_of(u.arg, "kind");
        let value_name = str_of(u.arg, "value_name");
        let at = format!("{} --{long}", u.command);
        let folder_name = long.ends_with("-dir") || long == "dir";
        let keyword_list = value_name.contains('|')
            && value_name.split('|').all(|w| {
                !w.is_empty()
                    && w.chars()
                        .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
            });
        if long == "output" && (kind != "path" || value_name.contains("DIR")) {
            problems.push(format!(
                "{at}: --output is always one output file (a folder is --out-dir)"
            ));
        }
        if value_name == "DIR" && !folder_name {
            problems.push(format!("{at}: a folder is named --*-dir"));
        }
        if folder_name && (kind != "path" || value_name != "DIR") {
            problems.push(format!(
                "{at}: a --*-dir flag is a path with value name DIR"
            ));
        }
        if long == "size" && value_name != "WxH" {
            problems.push(format!(
                "{at}: --size is always WxH (other shapes get their own names)"
            ));
        }
        if long == "json" && kind != "switch" {
            problems.push(format!("{at}: --json is a switch"));
        }
        if kind == "string" && keyword_list {
            problems.push(format!(
                "{at}: a value from a fixed list ({value_name}) is a clap value enum"
            ));
        }
        if !u.arg["positional"].as_bool().unwrap_or(false)
            && u.arg["help"].as_str().is_none_or(str::is_empty)
        {
            problems.push(format!("{at}: no help text"));
        }
    }
    problems
}

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
fn reference_dir() -> PathBuf {
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

fn compare_or_bless(schema: &Value, path: &Path, bless: bool) -> Result<(), String> {
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

/// The Markdown command-line reference of the given trees: a contents list,
/// then one section per command with its description and a table of its
/// arguments and flags.
#[must_use]
pub fn markdown(trees: &[&Value]) -> String {
    let mut out = String::from(
        "# Command-line reference\n\n\
         Generated from the binaries' definitions (`docs/reference/cli/*.json`); do not edit \
         by hand. To regenerate: `IFD_BLESS=1 cargo test -p ifd-cli -p ifd-brush -p \
         ifd-envrender --bins` (the schemas), then `IFD_BLESS=1 cargo test -p ifd-clidoc` \
         (this page). Every flag has one \
         meaning across the three binaries (checked by `ifd-clidoc`'s grammar test).\n\n",
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

#[cfg(test)]
mod workspace {
    //! The checked-in schemas of the three binaries (each binary's own test
    //! keeps its file current) read as one tool, and the Markdown reference
    //! is the one they generate.
    use super::*;

    fn schemas() -> Vec<Value> {
        BINARIES
            .iter()
            .map(|bin| {
                let path = reference_dir().join("cli").join(format!("{bin}.json"));
                let text = std::fs::read_to_string(&path)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            })
            .collect()
    }

    #[test]
    fn the_three_binaries_follow_one_grammar() {
        let schemas = schemas();
        let refs: Vec<&Value> = schemas.iter().collect();
        let problems = check_grammar(&refs, EXCEPTIONS);
        assert!(problems.is_empty(), "{}", problems.join("\n"));
    }

    #[test]
    fn the_markdown_reference_is_generated_from_the_schemas() {
        let schemas = schemas();
        let refs: Vec<&Value> = schemas.iter().collect();
        let text = markdown(&refs);
        let path = reference_dir().join("cli.md");
        if std::env::var_os("IFD_BLESS").is_some_and(|v| v == "1") {
            std::fs::write(&path, &text).expect("write cli.md");
            return;
        }
        let old = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            old == text,
            "{} is stale: regenerate the schemas with IFD_BLESS=1 cargo test -p ifd-cli -p \
             ifd-brush -p ifd-envrender --bins, then this page with IFD_BLESS=1 cargo test -p \
             ifd-clidoc",
            path.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::value_parser;

    fn tree(args: Vec<Arg>) -> Value {
        schema(Command::new("t").subcommand(Command::new("a").args(args)))
    }

    fn path_arg(long: &'static str, value_name: &'static str) -> Arg {
        Arg::new(long)
            .long(long)
            .value_name(value_name)
            .help("h")
            .value_parser(value_parser!(PathBuf))
    }

    #[test]
    fn a_flag_with_two_shapes_is_reported_unless_excepted() {
        let a = tree(vec![path_arg("table", "FILE")]);
        let b = schema(
            Command::new("u").arg(
                Arg::new("table")
                    .long("table")
                    .value_name("N")
                    .help("h")
                    .value_parser(value_parser!(usize)),
            ),
        );
        let problems = check_grammar(&[&a, &b], &[]);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].contains("--table has 2 shapes"), "{problems:?}");
        let excepted = check_grammar(
            &[&a, &b],
            &[Exception {
                long: "table",
                reason: "test",
            }],
        );
        assert!(excepted.is_empty(), "{excepted:?}");
    }

    #[test]
    fn output_folders_sizes_and_string_choices_are_reported() {
        let t = tree(vec![
            path_arg("output", "DIR").short('o'),
            path_arg("size", "N"),
            path_arg("plots", "DIR"),
            Arg::new("method")
                .long("method")
                .value_name("sh|maps")
                .help("h"),
        ]);
        let problems = check_grammar(&[&t], &[]);
        for needle in [
            "--output is always",
            "--size is always",
            "named --*-dir",
            "value enum",
        ] {
            assert!(
                problems.iter().any(|p| p.contains(needle)),
                "{needle}: {problems:?}"
            );
        }
    }

    #[test]
    fn enums_list_their_values_and_differ_per_command_freely() {
        let en = |values: [&'static str; 2]| {
            Arg::new("method")
                .long("method")
                .help("h")
                .value_parser(values)
        };
        let a = tree(vec![en(["x", "y"])]);
        let b = schema(Command::new("u").arg(en(["p", "q"])));
        assert_eq!(a["subcommands"][0]["args"][0]["kind"], "enum");
        assert!(check_grammar(&[&a, &b], &[]).is_empty());
        assert!(markdown(&[&a]).contains("Values: `x`, `y`."));
    }

    #[test]
    fn check_file_reports_the_command_that_changed() {
        let dir = std::env::temp_dir().join(format!("ifd-clidoc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("t.json");
        let a = tree(vec![path_arg("output", "FILE")]);
        std::fs::write(
            &path,
            format!("{}\n", serde_json::to_string_pretty(&a).expect("json")),
        )
        .expect("write");
        assert!(compare_or_bless(&a, &path, false).is_ok());
        let b = tree(vec![path_arg("output", "IMAGE")]);
        let err = compare_or_bless(&b, &path, false).expect_err("differs");
        assert!(err.contains("t a"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
