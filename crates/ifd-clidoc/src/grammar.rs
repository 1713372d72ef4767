//! The rules that make the four binaries read as one tool
//! (`../shared/STYLE.md`, "Command-line grammar").

use std::collections::BTreeMap;

use serde_json::Value;

use crate::Exception;
use crate::str_of;

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
