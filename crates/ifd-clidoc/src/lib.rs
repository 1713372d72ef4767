//! The command lines of `ifd`, `ifd-brush`, `ifd-envrender` and `ifd-paper` as
//! data.
//!
//! Three jobs, one representation:
//!
//! - [`schema`] turns a clap command tree into JSON: every subcommand, and for
//!   every flag its long and short names, value name, value *kind* (path,
//!   string, integer, number, enum with its values, flag, count), default and
//!   help. Each binary checks its schema into `docs/reference/cli/<bin>.json`
//!   and a test compares it with what the binary defines ([`check_file`]), so
//!   a change to a command line is deliberate and visible in review.
//! - [`check_grammar`] checks the rules that make the four binaries read as
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

mod files;
mod grammar;
mod markdown;
mod schema;

use serde_json::Value;

pub use crate::files::{check_binary, check_file};
pub use crate::grammar::check_grammar;
pub use crate::markdown::markdown;
pub use crate::schema::schema;

/// A flag allowed to break the one-meaning rule, with the reason.
#[derive(Debug, Clone, Copy)]
pub struct Exception {
    /// The long flag name, without dashes.
    pub long: &'static str,
    /// Why the flag means different things in different commands.
    pub reason: &'static str,
}

/// The flags allowed several shapes across the four binaries: none.
pub const EXCEPTIONS: &[Exception] = &[];

/// The binaries whose schemas are checked in under `docs/reference/cli/`.
pub const BINARIES: [&str; 4] = ["ifd", "ifd-brush", "ifd-envrender", "ifd-paper"];

pub(crate) fn str_of<'a>(v: &'a Value, key: &str) -> &'a str {
    v[key].as_str().unwrap_or("")
}

#[cfg(test)]
mod workspace {
    //! The checked-in schemas of the four binaries (each binary's own test
    //! keeps its file current) read as one tool, and the Markdown reference
    //! is the one they generate.
    use super::*;
    use crate::files::reference_dir;

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
    fn the_four_binaries_follow_one_grammar() {
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
             ifd-brush -p ifd-envrender -p ifd-paper --bins, then this page with IFD_BLESS=1 \
             cargo test -p ifd-clidoc",
            path.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use clap::{Arg, Command, value_parser};

    use super::*;
    use crate::files::compare_or_bless;

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
