//! What is queued for one peer, bounded by messages and bytes: [`Outbox`].

use std::collections::VecDeque;

/// The messages queued for a peer, oldest first, and their bytes.
#[derive(Debug, Default)]
pub(super) struct Outbox {
    queue: VecDeque<Vec<u8>>,
    /// Bytes in `queue`.
    queued: usize,
}

impl Outbox {
    /// Queues `bytes`, first dropping the oldest messages while `cap`
    /// messages or `cap_bytes` bytes (with `bytes`) are exceeded; returns
    /// how many were dropped.
    pub(super) fn push(&mut self, bytes: Vec<u8>, cap: usize, cap_bytes: usize) -> u64 {
        let mut dropped = 0;
        while !self.queue.is_empty() && (self.queue.len() >= cap || self.queued + bytes.len() > cap_bytes) {
            if let Some(old) = self.queue.pop_front() {
                self.queued -= old.len();
            }
            dropped += 1;
        }
        self.queued += bytes.len();
        self.queue.push_back(bytes);
        dropped
    }

    /// The oldest message, taken out.
    pub(super) fn pop(&mut self) -> Option<Vec<u8>> {
        let bytes = self.queue.pop_front()?;
        self.queued -= bytes.len();
        Some(bytes)
    }

    /// Whether nothing is queued.
    pub(super) fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Bytes queued.
    pub(super) fn bytes(&self) -> usize {
        self.queued
    }
}
