//! The host side of the emulated bench (`accelcal emulate`): a simulated unit's analog front end
//! feeding the QEMU node ([`frontend`]) and a dividing head driven over TCP ([`head`]), pure Rust
//! with std threads. Both read one head state ([`head::Head`], shared in an `Arc`) on one clock
//! ([`head::Clock`]): the server moves the head, the front end samples the unit in the head's
//! orientation at each set's time.
//!
//! Typical wiring: `Unit::read_for_node` → `FrontEnd::new`; `Head::new(Clock::start(), ..)` in an
//! `Arc`; `bind_head` + `spawn_head_server`; a thread running [`frontend::read_ctl`] on the node's
//! USART2 output and one running [`frontend::run_frontend`] into its input; set the stop flag and
//! join.

pub mod bench;
pub mod fault;
pub mod frontend;
pub mod head;
pub mod pty;
pub mod zaber;

pub use frontend::{
    read_ctl, run_frontend, CtlStats, FeCounters, FeStats, FrontEnd, FrontendError, PaceOptions,
};
pub use head::{
    bind_head, serve_head, spawn_head_server, Clock, Head, HeadPose, HeadServerError, HeadServerStats,
    HeadState, Motion,
};
