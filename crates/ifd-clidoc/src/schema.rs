//! A clap command tree as JSON: every subcommand, and for every flag its
//! names, value name, value kind, default and help.

use std::any::TypeId;
use std::path::PathBuf;

use clap::{Arg, ArgAction, Command};
use serde_json::{Value, json};

/// The JSON schema of a command tree (hidden commands and flags, if a
/// binary ever has any, left out: they are not part of its grammar).
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
