//! Which failures are the user's input to fix (exit code 2) and which come from the environment
//! (exit code 1).
//!
//! The rule is stated by the errors themselves, not by a list of input errors: an error is bad
//! input unless something in its chain says it comes from the environment: the file system while
//! writing an output ([`Environment`], attached where outputs are written), QEMU, the node's link
//! or a debug probe (the node module's own error types). A new error type of the core is
//! therefore bad input by default, which is what nearly every error of a calibration tool is (a
//! campaign, a recording, a record, an option); a panic is a bug.

use crate::error::Environment;

/// Whether an error is the user's input to fix: nothing in its chain comes from the environment.
pub fn is_bad_input(e: &anyhow::Error) -> bool {
    !e.chain().any(|c| {
        c.is::<Environment>()
            || c.is::<crate::error::Interrupted>()
            || c.is::<crate::verify::Failed>()
            || c.is::<crate::node::hil::HilError>()
            || c.is::<crate::node::flash::FlashError>()
            || c.is::<crate::node::link::LinkError>()
            || c.is::<crate::node::session::SessionError>()
            || c.is::<crate::node::head::HeadError>()
            || c.is::<crate::node::gdb::GdbError>()
    })
}

/// The process exit code of a failure: 130 when the user stopped the command
/// ([`crate::error::Interrupted`]), 2 for bad input, 1 for the environment.
pub fn code(e: &anyhow::Error) -> i32 {
    if e.chain().any(|c| c.is::<crate::error::Interrupted>()) {
        130
    } else if is_bad_input(e) {
        2
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::{bad, environment};

    #[test]
    fn errors_are_bad_input_unless_the_environment_failed() {
        assert!(is_bad_input(&bad("x.csv:3:1: expected a number")));
        // An error type nobody listed is bad input by default.
        #[derive(Debug, thiserror::Error)]
        #[error("new kind of input error")]
        struct NewInputError;
        assert!(is_bad_input(&anyhow::Error::new(NewInputError).context("reading")));
        let io = std::io::Error::new(std::io::ErrorKind::StorageFull, "disk full");
        let e = environment("writing out.json", io).context("fit");
        assert!(!is_bad_input(&e));
        assert_eq!(format!("{e:#}"), "fit: writing out.json: disk full");
        assert!(!is_bad_input(&anyhow::Error::new(crate::node::hil::HilError::Timeout(
            std::time::Duration::from_secs(3)
        ))));
    }
}
