//! Point queries from the main world: asked in one frame, taken by the render
//! world at that frame's extraction, answered a frame or two later by its
//! gather (`SnowFrame::with_queries`) and sent back through a channel.

use std::ops::Range;

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

/// Asks the snow at points (depth, compaction, normal): a main-world
/// resource. Answers come a frame or two later (received in
/// [`crate::SnowSystems::Receive`]); nothing waits. Every request asked in a
/// frame goes to the GPU in one gather.
#[derive(Resource, Default, Debug)]
pub struct SnowQuery {
    next: u64,
    requests: Vec<(SnowTicket, Vec<Vec2>)>,
    answers: Vec<SnowAnswers>,
}

impl SnowQuery {
    /// Asks about `points` (world x, z); the ticket names the answer.
    pub fn ask(&mut self, points: &[Vec2]) -> SnowTicket {
        let ticket = SnowTicket(self.next);
        self.next += 1;
        self.requests.push((ticket, points.to_vec()));
        ticket
    }

    /// The answer to `ticket` once it has arrived (taken: a second call returns `None`).
    pub fn take(&mut self, ticket: SnowTicket) -> Option<SnowAnswers> {
        let k = self.answers.iter().position(|a| a.ticket == ticket)?;
        Some(self.answers.remove(k))
    }

    /// The newest answer that has arrived, if any, without taking it.
    #[must_use]
    pub fn latest(&self) -> Option<&SnowAnswers> {
        self.answers.iter().max_by_key(|a| a.ticket)
    }

    /// The questions asked since the last extraction (taken by the render world).
    pub(crate) fn take_requests(&mut self) -> Vec<(SnowTicket, Vec<Vec2>)> {
        std::mem::take(&mut self.requests)
    }

    /// Answers received from the render world; the oldest beyond [`KEPT_ANSWERS`] are dropped.
    pub(crate) fn deliver(&mut self, answers: Vec<SnowAnswers>) {
        self.answers.extend(answers);
        let excess = self.answers.len().saturating_sub(KEPT_ANSWERS);
        self.answers.drain(..excess);
    }
}

/// The library's answer to one combined gather split back into the callers' answers.
pub(crate) fn split_answers(answers: &PointAnswers, ranges: &[(SnowTicket, Range<usize>)]) -> Vec<SnowAnswers> {
    ranges
        .iter()
        .map(|(ticket, range)| SnowAnswers {
            ticket: *ticket,
            frame: answers.frame,
            points: answers.points[range.clone()].to_vec(),
            samples: answers.samples[range.clone()].to_vec(),
        })
        .collect()
}
