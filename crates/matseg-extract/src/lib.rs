//! From photos to material placements: the soft maps of pipeline.md §1 and
//! the uniform textures of section 4 and the PBR materials of section 5.

#![warn(missing_docs)]

pub mod material_library;
pub mod pbr;
pub mod pbr_mix;
pub mod soft_maps;
pub mod textures;

pub use soft_maps::{
    check_probabilities, combine_maps, draw_channel_map, make_soft_maps, random_channel_placement,
    random_placement, CombineRecord, CombinedMaps, MapNormalisation, MapRecord, OutOfRange, RawMap,
    SoftMapError, SoftMapRecipe, SoftMaps, MAX_MAPS,
};
