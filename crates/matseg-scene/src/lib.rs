//! Scene recipes: the 2D composer of pipeline.md §2 and the 3D scene builder
//! of pipeline.md §3, with exact soft annotations.

#![warn(missing_docs)]

pub mod annotation;
pub mod compose2d;
pub mod material;
pub mod recipe;
pub mod recipe3d;
pub mod scene3d;
pub mod sequence;

pub use annotation::{
    blend_annotation_colour, colourise, quantise_fractions, quantise_weights, QuantisedAnnotation,
    PALETTE,
};
pub use compose2d::{
    generate_2d, BackgroundRecord, ComposeError, Scene2d, SceneRecord, SourceRef, Sources,
};
pub use material::{Fill, MaterialRecord, MaterialSource, ShadingRecord};
pub use recipe::{CompositionRecipe, Recipe2d, RecipeError, SceneDraws, SceneShape};
pub use recipe3d::Recipe3d;
pub use scene3d::{build_scene_3d, Scene3dError, Sources3d};
pub use sequence::CameraPath;
