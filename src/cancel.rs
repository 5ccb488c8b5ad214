//! Cooperative cancellation of long library calls (a fit, a render): the caller keeps a
//! [`Cancel`] and sets it from another thread; the work checks it at its natural steps
//! (an LM iteration, a model evaluation, an image row) and ends with
//! [`Error::Interrupted`]. The binary needs none (a signal ends the process, see
//! [`crate::io::install_interrupt_cleanup`]); an embedding that must survive the
//! interrupt does (the Python module turns Ctrl-C into a set flag and a
//! `KeyboardInterrupt`, issue 63).

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A shared flag that asks a running call to stop. The default is a token nobody can
/// set (the work never stops early), so options that carry one cost nothing unless a
/// caller makes one with [`Cancel::new`].
#[derive(Clone, Debug, Default)]
pub struct Cancel(Option<Arc<AtomicBool>>);

impl Cancel {
    /// A token that [`Cancel::cancel`] can set (clones share the flag).
    pub fn new() -> Cancel {
        Cancel(Some(Arc::new(AtomicBool::new(false))))
    }

    /// Ask the work holding a clone of this token to stop.
    pub fn cancel(&self) {
        if let Some(f) = &self.0 {
            f.store(true, Ordering::Relaxed);
        }
    }

    /// Whether [`Cancel::cancel`] was called on this token or a clone.
    pub fn is_cancelled(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// [`Error::Interrupted`] once cancelled.
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Interrupted)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_the_default_never_stops() {
        let c = Cancel::new();
        let d = c.clone();
        assert!(c.check().is_ok());
        d.cancel();
        assert!(c.is_cancelled());
        assert!(matches!(c.check(), Err(Error::Interrupted)));
        let none = Cancel::default();
        none.cancel();
        assert!(!none.is_cancelled());
    }
}
