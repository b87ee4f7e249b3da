//! Footsteps: entities marked [`SnowFoot`] (a paw or a foot bone, a sole
//! marker) are asked about through [`SnowQuery`] every frame; when a foot
//! comes down onto the snow a [`SnowFootstep`] message is written, for sound
//! and particles.

use bevy::prelude::*;

use crate::SnowSystems;
use crate::query::{SnowQuery, SnowTicket};

/// What kind of foot made a step.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Clone, Debug, Default, PartialEq, Hash)]
pub enum FootKind {
    /// An animal's paw.
    #[default]
    Paw,
    /// A person's foot.
    Foot,
}

/// A foot whose steps on the snow are reported: put it on the entity whose
/// origin is the sole (a paw bone, or a child placed at the sole).
#[derive(Component, Reflect, Clone, Copy, Debug)]
#[reflect(Component, Clone, Debug)]
#[require(Transform)]
pub struct SnowFoot {
    /// Paw or foot, copied into the messages.
    pub kind: FootKind,
    /// A sole at most this high over the displayed snow surface (m) touches it.
    pub contact_m: f32,
    down: bool,
}

impl SnowFoot {
    /// A foot of `kind` that touches the snow within 3 cm.
    #[must_use]
    pub fn new(kind: FootKind) -> Self {
        Self { kind, contact_m: 0.03, down: false }
    }

    /// The same foot touching the snow within `contact_m` (a bone that sits above the sole).
    #[must_use]
    pub fn with_contact(mut self, contact_m: f32) -> Self {
        self.contact_m = contact_m;
        self
    }
}

/// A foot came down on the snow.
#[derive(Message, Clone, Copy, Debug, PartialEq)]
pub struct SnowFootstep {
    /// The [`SnowFoot`] entity.
    pub foot: Entity,
    /// Paw or foot.
    pub kind: FootKind,
    /// Where the sole met the snow: its x, z and the snow surface's height.
    pub position: Vec3,
    /// Snow depth there before the step pressed it (m), from the query answer.
    pub depth_m: f32,
    /// How far below untouched snow the surface there is (m): the footprint so far.
    pub sinkage_m: f32,
}

pub(crate) fn build(app: &mut App) {
    app.add_message::<SnowFootstep>().add_systems(PostUpdate, detect_footsteps.in_set(SnowSystems::Footsteps));
}

/// The request in flight: its ticket, the feet it asked about (in order), and its age in frames.
#[derive(Default)]
struct Asked(Option<(SnowTicket, Vec<Entity>, u32)>);

/// A request unanswered for this many frames was skipped by the GPU side (busy staging): ask anew.
const GIVE_UP_FRAMES: u32 = 6;

fn detect_footsteps(
    mut query: ResMut<SnowQuery>,
    mut asked: Local<Asked>,
    mut feet: Query<(Entity, &mut SnowFoot, &GlobalTransform)>,
    mut steps: MessageWriter<SnowFootstep>,
) {
    if let Some((_, _, age)) = &mut asked.0 {
        *age += 1;
        if *age > GIVE_UP_FRAMES {
            asked.0 = None;
        }
    }
    if let Some((ticket, entities, _)) = &asked.0
        && let Some(answers) = query.take(*ticket)
    {
        for (entity, sample) in entities.iter().zip(&answers.samples) {
            let (Ok((_, mut foot, transform)), Some(s)) = (feet.get_mut(*entity), sample) else { continue };
            let p = transform.translation();
            let down = p.y - s.surface_m <= foot.contact_m;
            if down && !foot.down {
                steps.write(SnowFootstep {
                    foot: *entity,
                    kind: foot.kind,
                    position: Vec3::new(p.x, s.surface_m, p.z),
                    depth_m: s.depth_m(),
                    sinkage_m: s.sinkage_m(),
                });
            }
            foot.down = down;
        }
        asked.0 = None;
    }
    if asked.0.is_none() {
        let (entities, points): (Vec<Entity>, Vec<Vec2>) = feet.iter().map(|(e, _, t)| (e, t.translation().xz())).unzip();
        if !entities.is_empty() {
            asked.0 = Some((query.ask_quietly(&points), entities, 0));
        }
    }
}
