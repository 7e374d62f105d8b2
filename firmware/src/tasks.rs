//! The embassy tasks: thin, non-generic wrappers that bind the application's loops
//! ([`crate::app::node`]) to the chosen board's concrete types.

use embassy_executor::Spawner;

use crate::app::node::{self, Node};
use crate::board::{Board, LinkRxImpl, LinkTxImpl, SampleClockImpl, SourceImpl};

#[embassy_executor::task]
async fn link_rx(rx: LinkRxImpl, clock: SampleClockImpl, node: Node) {
    node::serve_link(rx, clock, node).await
}

#[embassy_executor::task]
async fn link_tx(tx: LinkTxImpl) {
    node::transmit(tx).await
}

#[embassy_executor::task]
async fn status(node: Node) {
    node::report_status(node).await
}

#[embassy_executor::task]
async fn sampler(source: SourceImpl, node: Node) {
    node::stream_samples(source, node).await
}

/// Spawns every task of the node. Panics only if a task is spawned twice (a programming error at
/// init).
pub fn spawn_all(spawner: Spawner, board: Board, node: Node) {
    spawner.spawn(link_tx(board.tx).expect("link_tx spawned once"));
    spawner.spawn(link_rx(board.rx, board.clock, node).expect("link_rx spawned once"));
    spawner.spawn(status(node).expect("status spawned once"));
    spawner.spawn(sampler(board.source, node).expect("sampler spawned once"));
}
