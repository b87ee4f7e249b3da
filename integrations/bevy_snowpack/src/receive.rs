//! The main world's end of the way back from the render world: what arrived
//! on the channel ([`crate::from_render::FromRender`]) is put where the main
//! world reads it ([`SnowQuery`] answers, [`SnowControl`] results, coats) at
//! the start of its frame, or during extraction.

use bevy::prelude::*;
use bevy::transform::TransformSystems;

use crate::coat::ArrivedCoats;
use crate::control::SnowControl;
use crate::from_render::{FromRender, FromRenderWorld};
use crate::query::SnowQuery;
use crate::systems::{Delivered, SnowSystems};

/// The plugin's sets in order, and the delivery of what arrived.
pub(crate) fn build(app: &mut App) {
    app.configure_sets(PostUpdate, (SnowSystems::Gather.after(TransformSystems::Propagate), SnowSystems::Footsteps.after(SnowSystems::Gather)))
        .add_systems(PreUpdate, receive_from_render.in_set(SnowSystems::Receive).in_set(Delivered));
}

/// Moves what arrived from the render world into [`SnowQuery`] and [`SnowControl`].
pub(crate) fn receive_from_render(
    mut from: ResMut<FromRenderWorld>,
    mut query: ResMut<SnowQuery>,
    mut control: ResMut<SnowControl>,
    mut coats: ResMut<ArrivedCoats>,
) {
    deliver(from.drain(), &mut query, &mut control, &mut coats);
}

/// Receives in the main world during extraction (the render world's
/// `take_requests`), too: what the render world's startup reported (a
/// loaded save) runs in the first update's extraction, before its
/// `ExtractSchedule`, so it is there once that update returns, as it is for
/// a game's first `Update`.
pub(crate) fn receive_in(main_world: &mut World) {
    let Some(arrived) = main_world.get_resource_mut::<FromRenderWorld>().map(|mut f| f.drain()) else { return };
    if arrived.is_empty() {
        return;
    }
    main_world.resource_scope(|world, mut query: Mut<SnowQuery>| {
        world.resource_scope(|world, mut coats: Mut<ArrivedCoats>| {
            if let Some(mut control) = world.get_resource_mut::<SnowControl>() {
                deliver(arrived, &mut query, &mut control, &mut coats);
            }
        });
    });
}

/// Puts what arrived where the main world reads it.
fn deliver(arrived: Vec<FromRender>, query: &mut SnowQuery, control: &mut SnowControl, coats: &mut ArrivedCoats) {
    for message in arrived {
        match message {
            FromRender::Answers(answers) => query.deliver(answers),
            FromRender::LoadedSave(loaded) => control.loaded_save = Some(loaded),
            FromRender::Saved(result) => control.arrive_save(result),
            FromRender::ObjectStats(stats) => control.arrive_stats(stats),
            FromRender::Coat(entity, thickness_m) => {
                coats.0.insert(entity, thickness_m);
            }
        }
    }
}
