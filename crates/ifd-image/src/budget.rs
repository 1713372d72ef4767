//! A memory budget that refuses images whose samples would not fit.

use crate::{ImageError, fmt_bytes};

/// The largest number of bytes an image (or derived data) may need.
///
/// The default is 75% of the machine's physical memory (read from
/// `/proc/meminfo`; 8 GiB when that cannot be read).
///
/// ```
/// use ifd_image::MemoryBudget;
/// let b = MemoryBudget::bytes(1 << 20);
/// assert!(b.check(1000).is_ok());
/// assert!(b.check(2 << 20).unwrap_err().to_string().contains("2.0 MiB"));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    bytes: u64,
}

impl MemoryBudget {
    /// A budget of exactly `bytes`.
    #[must_use]
    pub const fn bytes(bytes: u64) -> Self {
        Self { bytes }
    }

    /// 75% of physical memory.
    #[must_use]
    pub fn default_for_machine() -> Self {
        let total = physical_memory().unwrap_or(8 << 30);
        Self {
            bytes: total / 4 * 3,
        }
    }

    /// The budget in bytes.
    #[must_use]
    pub fn limit(self) -> u64 {
        self.bytes
    }

    /// Checks that `needed` bytes fit.
    ///
    /// # Errors
    /// [`ImageError::TooLarge`] saying how much was needed and the budget
    /// (without a file: [`ImageError::in_file`] adds one).
    pub fn check(self, needed: u64) -> Result<(), ImageError> {
        if needed > self.bytes {
            Err(ImageError::TooLarge {
                path: None,
                needed_bytes: needed,
                budget_bytes: self.bytes,
            })
        } else {
            Ok(())
        }
    }

    /// A human-readable form of the budget.
    #[must_use]
    pub fn describe(self) -> String {
        fmt_bytes(self.bytes)
    }
}

/// Total physical memory in bytes, from `/proc/meminfo` (Linux).
#[must_use]
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
