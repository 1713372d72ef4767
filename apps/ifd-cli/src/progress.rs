//! The progress bars of the commands' long steps, on standard error, in one
//! style. indicatif draws nothing when standard error is not a terminal (a
//! pipe, a file, the tests), so a bar never mixes with a report.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar `LABEL [====] POS/LEN UNIT [elapsed<eta]` of `len` steps (0 when
/// the work reports its total itself, through [`track`]); `unit` may be
/// empty.
pub fn bar(label: &str, unit: &str, len: u64) -> ProgressBar {
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{label} {{bar:30}} {{pos}}/{{len}}{unit} [{{elapsed}}<{{eta}}]"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// The `(done, total)` callback of the libraries' long steps: moves `bar`
/// to `done` of `total`.
pub fn track(bar: &ProgressBar) -> impl Fn(usize, usize) + Sync + '_ {
    move |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    }
}

/// A spinner `* LABEL MESSAGE [elapsed]` for work of unknown length; the
/// work sets the message and ticks it.
pub fn spinner(label: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template(&format!("{{spinner}} {label} {{msg}} [{{elapsed}}]"))
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar
}
