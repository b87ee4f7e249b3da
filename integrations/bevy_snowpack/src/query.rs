//! Point queries from the main world: asked in one frame, taken by the render
//! world at that frame's extraction, answered a frame or two later by its
//! gather (`SnowFrame::with_queries`) and sent back through a channel.
//!
//! An answer is announced to observers ([`SnowAnswered`]) when it arrives and
//! kept for [`SnowQuery::take`] (polling): a game uses either.

use std::ops::Range;

use bevy::prelude::*;
use snowpack::{PointAnswers, PointSample};

use crate::SnowSystems;

/// Which request an answer belongs to (one per [`SnowQuery::ask`]).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[reflect(Clone, Debug, Default, PartialEq, Hash)]
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

/// An answer to [`SnowQuery::ask`] has arrived: an event for observers
/// (`app.add_observer(|answered: On<SnowAnswered>| ...)`), triggered in
/// [`SnowSystems::Receive`] of the frame it arrives in. The answer is also
/// kept for [`SnowQuery::take`]. The plugin's own questions (footsteps,
/// [`crate::FeelsSnow`]) are not announced.
#[derive(Event, Clone, Debug, PartialEq)]
pub struct SnowAnswered {
    /// The answer.
    pub answers: SnowAnswers,
}

/// Answers kept for callers that have not taken them yet; older ones are dropped.
const KEPT_ANSWERS: usize = 64;

/// Asks the snow at points (depth, compaction, normal): a main-world
/// resource. Answers come a frame or two later (received in
/// [`crate::SnowSystems::Receive`]); nothing waits. Every request asked in a
/// frame goes to the GPU in one gather.
#[derive(Resource, Reflect, Default, Debug)]
#[reflect(Resource, Debug, Default)]
pub struct SnowQuery {
    next: u64,
    #[reflect(ignore)]
    requests: Vec<(SnowTicket, Vec<Vec2>)>,
    #[reflect(ignore)]
    answers: Vec<SnowAnswers>,
    /// Tickets whose answers are announced ([`SnowAnswered`]) when they arrive.
    #[reflect(ignore)]
    announced: Vec<SnowTicket>,
    /// Answers arrived and not yet announced.
    #[reflect(ignore)]
    to_announce: Vec<SnowAnswers>,
}

impl SnowQuery {
    /// Asks about `points` (world x, z); the ticket names the answer, which
    /// comes as a [`SnowAnswered`] event and through [`Self::take`].
    pub fn ask(&mut self, points: &[Vec2]) -> SnowTicket {
        let ticket = self.ask_quietly(points);
        self.announced.push(ticket);
        ticket
    }

    /// Asks without announcing the answer (the plugin's own questions).
    pub(crate) fn ask_quietly(&mut self, points: &[Vec2]) -> SnowTicket {
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
        for answer in &answers {
            if let Some(k) = self.announced.iter().position(|t| *t == answer.ticket) {
                self.announced.swap_remove(k);
                self.to_announce.push(answer.clone());
            }
        }
        // Requests the GPU side skipped never answer: their tickets are not kept forever.
        let oldest_kept = self.next.saturating_sub(4 * KEPT_ANSWERS as u64);
        self.announced.retain(|t| t.0 >= oldest_kept);
        self.answers.extend(answers);
        let excess = self.answers.len().saturating_sub(KEPT_ANSWERS);
        self.answers.drain(..excess);
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_systems(PreUpdate, announce_answers.in_set(SnowSystems::Receive).after(crate::systems::Delivered));
}

/// Triggers a [`SnowAnswered`] for each announced answer that arrived.
fn announce_answers(mut commands: Commands, mut query: ResMut<SnowQuery>) {
    if query.to_announce.is_empty() {
        return;
    }
    for answers in std::mem::take(&mut query.to_announce) {
        commands.trigger(SnowAnswered { answers });
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
