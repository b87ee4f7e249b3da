//! The worker thread that owns the [`TileStore`]: the requests the frame
//! sends it and the replies it sends back, the loop that answers them (loads
//! first), and [`Worker`], the frame's end of the two channels.

use snowpack_share::persist::TileStoreExt;
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::persist::{StoreError, TileData, TileKey, TileStore};

/// What the frame asks of the worker. `seq` orders requests and replies.
pub(super) enum Request {
    Load {
        seq: u64,
        key: TileKey,
    },
    Write {
        seq: u64,
        tile: Arc<TileData>,
    },
    Flush {
        seq: u64,
    },
    WriteState {
        seq: u64,
        name: String,
        bytes: Vec<u8>,
    },
    ReadState {
        seq: u64,
        name: String,
    },
    BeginSaves {
        seq: u64,
    },
    Commit {
        seq: u64,
        name: String,
        bytes: Vec<u8>,
    },
    /// Lets the tests kill the worker the way a bug would.
    #[cfg(test)]
    Panic,
    /// Lets the tests hold the worker until `gate` is sent to or dropped;
    /// `entered` is told when the worker is held.
    #[cfg(test)]
    Pause {
        seq: u64,
        gate: Receiver<()>,
        entered: Option<Sender<()>>,
    },
}

/// The store's size after a request.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct DiskNumbers {
    pub(super) tiles: usize,
    pub(super) bytes: u64,
    pub(super) evicted: u64,
}

/// The worker's answer to request `seq`, with the store's size after it.
pub(super) struct Reply {
    pub(super) seq: u64,
    pub(super) disk: DiskNumbers,
    pub(super) outcome: Outcome,
}

/// What a request came to.
pub(super) enum Outcome {
    Loaded {
        key: TileKey,
        result: Result<Option<TileData>, StoreError>,
        /// The write (its `seq`) still queued that answered this load.
        queued: Option<u64>,
    },
    /// The file's size on success.
    Written {
        key: TileKey,
        result: Result<u64, StoreError>,
    },
    Flushed,
    StateWritten(Result<(), StoreError>),
    StateRead(Result<Option<Vec<u8>>, StoreError>),
}

/// The frame's end of the worker thread: the request channel (none for a
/// memory-only streamer), the reply channel, the thread and the last `seq`.
pub(super) struct Worker {
    requests: Option<Sender<Request>>,
    replies: Receiver<Reply>,
    thread: Option<JoinHandle<()>>,
    seq: u64,
}

impl Worker {
    /// Starts the worker thread ("snowpack-tiles"), which owns `store`.
    ///
    /// If the thread cannot be started, the request channel's other end is
    /// gone: the first send or poll finds it closed.
    pub(super) fn spawn(store: TileStore) -> Self {
        let (request_tx, request_rx) = mpsc::channel();
        let (reply_tx, reply_rx) = mpsc::channel();
        let thread = std::thread::Builder::new().name("snowpack-tiles".to_owned()).spawn(move || work(store, &request_rx, &reply_tx));
        let thread = match thread {
            Ok(handle) => Some(handle),
            Err(e) => {
                // The closure, and with it the reply sender, is dropped: the
                // first poll finds the channel closed and reports WorkerGone.
                tracing::error!("tile store: cannot start the worker thread: {e}");
                None
            }
        };
        Self { requests: Some(request_tx), replies: reply_rx, thread, seq: 0 }
    }

    /// No worker: nothing is ever asked or answered (a memory-only streamer).
    pub(super) fn none() -> Self {
        // A channel whose sender is gone.
        let (_, replies) = mpsc::channel();
        Self { requests: None, replies, thread: None, seq: 0 }
    }

    /// Whether there is a channel to a worker (there is none for a memory-only streamer).
    pub(super) fn has_channel(&self) -> bool {
        self.requests.is_some()
    }

    /// Sends a request numbered with the next `seq`; `None` if the worker is gone.
    pub(super) fn send(&mut self, request: impl FnOnce(u64) -> Request) -> Option<u64> {
        self.seq += 1;
        let sent = self.requests.as_ref().is_some_and(|tx| tx.send(request(self.seq)).is_ok());
        sent.then_some(self.seq)
    }

    /// The next reply, waiting at most `limit`.
    pub(super) fn recv_timeout(&self, limit: Duration) -> Result<Reply, RecvTimeoutError> {
        self.replies.recv_timeout(limit)
    }

    /// The next reply if one has arrived.
    pub(super) fn try_recv(&self) -> Result<Reply, TryRecvError> {
        self.replies.try_recv()
    }

    /// Closes the request channel: the worker's loop ends once its queue is done.
    pub(super) fn close(&mut self) {
        drop(self.requests.take());
    }

    /// The thread, to join or leave behind.
    pub(super) fn take_thread(&mut self) -> Option<JoinHandle<()>> {
        self.thread.take()
    }
}

/// The worker: answers requests until the streamer hangs up, in order
/// except that loads go first (see the module docs). Never panics on I/O
/// errors: they go back in the replies.
fn work(mut store: TileStore, requests: &Receiver<Request>, replies: &Sender<Reply>) {
    let mut queue: VecDeque<Request> = VecDeque::new();
    loop {
        // Block only when nothing is queued; then take all that has arrived.
        if queue.is_empty() {
            match requests.recv() {
                Ok(request) => queue.push_back(request),
                Err(_) => return,
            }
        }
        queue.extend(requests.try_iter());
        let load = queue.iter().enumerate().find_map(|(at, r)| match r {
            Request::Load { seq, key } => Some((at, *seq, *key)),
            _ => None,
        });
        let (seq, outcome) = match load {
            Some((at, seq, key)) => {
                queue.remove(at);
                // The newest write of the same tile queued before the load is its answer.
                let queued = queue.iter().take(at).rev().find_map(|r| match r {
                    Request::Write { seq, tile } if tile.key == key => Some((*seq, Arc::clone(tile))),
                    _ => None,
                });
                let outcome = match queued {
                    Some((w, tile)) => Outcome::Loaded { key, result: Ok(Some((*tile).clone())), queued: Some(w) },
                    None => Outcome::Loaded { key, result: store.read(key), queued: None },
                };
                (seq, outcome)
            }
            None => match queue.pop_front() {
                Some(request) => answer(&mut store, request),
                None => continue,
            },
        };
        let disk = DiskNumbers { tiles: store.disk_tiles(), bytes: store.disk_bytes(), evicted: store.evicted() };
        // The streamer may be dropping: keep going, the queued writes still matter.
        let _ = replies.send(Reply { seq, disk, outcome });
    }
}

/// Does one request other than a load jumping the queue.
fn answer(store: &mut TileStore, request: Request) -> (u64, Outcome) {
    match request {
        Request::Load { seq, key } => (seq, Outcome::Loaded { key, result: store.read(key), queued: None }),
        Request::Write { seq, tile } => {
            let result = store.write(&tile).map(|()| store.tile_bytes(tile.key).unwrap_or(0));
            (seq, Outcome::Written { key: tile.key, result })
        }
        Request::Flush { seq } => (seq, Outcome::Flushed),
        Request::WriteState { seq, name, bytes } => (seq, Outcome::StateWritten(store.write_state(&name, &bytes))),
        Request::ReadState { seq, name } => (seq, Outcome::StateRead(store.read_state(&name))),
        Request::BeginSaves { seq } => {
            store.begin_saves();
            (seq, Outcome::Flushed)
        }
        Request::Commit { seq, name, bytes } => (seq, Outcome::StateWritten(store.commit(&[(&name, &bytes)]))),
        #[cfg(test)]
        Request::Panic => panic!("the tile worker panics (as a test asked)"),
        #[cfg(test)]
        Request::Pause { seq, gate, entered } => {
            if let Some(entered) = entered {
                let _ = entered.send(());
            }
            let _ = gate.recv();
            (seq, Outcome::Flushed)
        }
    }
}
