//! Scene recipes: the 2D composer of SPEC section 2 with exact soft annotations.

#![warn(missing_docs)]

pub mod annotation;
pub mod compose2d;
pub mod material;
pub mod recipe;

pub use annotation::{colorize, quantise_weights, QuantisedAnnotation, PALETTE};
pub use compose2d::{
    generate_2d, BackgroundRecord, Scene2d, SceneError, SceneRecord, SourceRef, Sources,
};
pub use material::{Fill, MaterialRecord, MaterialSource, ShadingRecord};
pub use recipe::{CompositionRecipe, Recipe2d, RecipeError, SceneDraws, SceneShape};
