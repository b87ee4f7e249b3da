//! CPU twin of `terrain_bake.wgsl`: the terrain mesh drawn from above into a
//! grid, keeping the highest surface per texel centre (the GPU's depth test).

pub use snowpack::low_level::terrain::draw_from_above as draw;
