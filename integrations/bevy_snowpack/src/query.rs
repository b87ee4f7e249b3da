//! Point queries from the main world: asked in one frame, answered a frame or
//! two later by the render world's gather (`SnowFrame::with_queries`).

use std::ops::Range;
use std::sync::{Arc, Mutex, MutexGuard};

use bevy::prelude::*;
use snowpack::{PointAnswers, PointSample};

/// Which request an answer belongs to (one per [`SnowQuery::ask`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SnowTicket(pub u64);

/// The answer to one request.
#[derive(Clone, Debug, PartialEq)]
pub struct SnowAnswers {
    /// The request answered.
    pub ticket: SnowTicket,
    /// The deformation frame whose snow this is.
    pub frame: u64,
    /// The points as asked (world x, z).
    pub points: Vec<Vec2>,
    /// The snow at each point (`None` outside the window).
    pub samples: Vec<Option<PointSample>>,
}

/// Answers kept for callers that have not taken them yet; older ones are dropped.
const KEPT_ANSWERS: usize = 64;

#[derive(Default)]
struct Shared {
    next: u64,
    requests: Vec<(SnowTicket, Vec<Vec2>)>,
    answers: Vec<SnowAnswers>,
}

/// Asks the snow at points (depth, compaction, normal): a resource shared by
/// the main and the render world. Answers come a frame or two later; nothing
/// waits. Every request asked in a frame goes to the GPU in one gather.
#[derive(Resource, Clone, Default)]
pub struct SnowQuery(Arc<Mutex<Shared>>);

impl SnowQuery {
    fn lock(&self) -> MutexGuard<'_, Shared> {
        // A panic elsewhere while holding the lock leaves plain data behind: keep using it.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Asks about `points` (world x, z); the ticket names the answer.
    pub fn ask(&self, points: &[Vec2]) -> SnowTicket {
        let mut s = self.lock();
        let ticket = SnowTicket(s.next);
        s.next += 1;
        s.requests.push((ticket, points.to_vec()));
        ticket
    }

    /// The answer to `ticket` once it has arrived (taken: a second call returns `None`).
    pub fn take(&self, ticket: SnowTicket) -> Option<SnowAnswers> {
        let mut s = self.lock();
        let k = s.answers.iter().position(|a| a.ticket == ticket)?;
        Some(s.answers.remove(k))
    }

    /// The newest answer that has arrived, if any, without taking it.
    #[must_use]
    pub fn latest(&self) -> Option<SnowAnswers> {
        self.lock().answers.iter().max_by_key(|a| a.ticket).cloned()
    }

    pub(crate) fn take_requests(&self) -> Vec<(SnowTicket, Vec<Vec2>)> {
        std::mem::take(&mut self.lock().requests)
    }

    pub(crate) fn deliver(&self, answers: &PointAnswers, ranges: &[(SnowTicket, Range<usize>)]) {
        let mut s = self.lock();
        for (ticket, range) in ranges {
            s.answers.push(SnowAnswers {
                ticket: *ticket,
                frame: answers.frame,
                points: answers.points[range.clone()].to_vec(),
                samples: answers.samples[range.clone()].to_vec(),
            });
        }
        let excess = s.answers.len().saturating_sub(KEPT_ANSWERS);
        s.answers.drain(..excess);
    }
}
