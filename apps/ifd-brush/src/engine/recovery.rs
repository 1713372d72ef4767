//! The engine's journal: every finished stroke, undo and redo appended,
//! and an interrupted session's journal offered for recovery.

use std::path::PathBuf;

use super::Engine;
use crate::journal::{Journal, Recovered};
use crate::strokes::Action;

impl Engine {
    /// Journals every stroke, undo and redo of documents opened from a file
    /// in `dir` ([`crate::journal`]); `announce` prints each saved entry on
    /// stderr. `None` turns journaling off. Applies from the next
    /// [`Engine::set_image`].
    pub fn set_journal_dir(&mut self, dir: Option<PathBuf>, announce: bool) {
        self.journal.dir = dir;
        self.journal.announce = announce;
    }

    /// The journal of an interrupted session on the current image, when the
    /// last [`Engine::set_image`] found one: offer it, then call
    /// [`Engine::resolve_recovery`].
    #[must_use]
    pub fn recoverable(&self) -> Option<&Recovered> {
        self.journal.pending.as_ref()
    }

    /// Applies (`recover`) or discards the journal of an interrupted session
    /// and starts this session's journal (which then holds the recovered
    /// edits too). Returns the dabs applied.
    ///
    /// # Errors
    /// As [`Engine::replay`].
    pub fn resolve_recovery(&mut self, recover: bool) -> anyhow::Result<usize> {
        let Some(r) = self.journal.pending.take() else {
            return Ok(0);
        };
        self.start_journal();
        if recover {
            self.replay(&r.strokes)
        } else {
            Ok(0)
        }
    }

    /// Ends journaling cleanly (the app closes normally): the journal is
    /// deleted, there is nothing to recover. A pending journal is kept.
    pub fn close_journal(&mut self) {
        if let Some(j) = self.journal.open.take() {
            j.remove();
        }
    }

    pub(super) fn start_journal(&mut self) {
        self.journal.open = None;
        let (Some(dir), Some(path), Some(image)) = (&self.journal.dir, &self.path, &self.image)
        else {
            return;
        };
        match Journal::create(dir, path, image) {
            Ok(mut j) => {
                j.set_announce(self.journal.announce);
                self.journal.open = Some(j);
            }
            Err(e) => eprintln!("warning: edits are not journaled: {e:#}"),
        }
    }

    pub(super) fn journal_append(&mut self, action: &Action) {
        if let Some(j) = &mut self.journal.open
            && let Err(e) = j.append(action)
        {
            eprintln!("warning: journaling stopped: {e:#}");
            self.journal.open = None;
        }
    }
}
