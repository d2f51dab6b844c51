//! The 3D half of matseg: triangle meshes and procedural shapes, a BVH, a
//! pinhole camera, a GGX microfacet BSDF with metallic/roughness, normal and
//! bump maps and dielectric transmission, HDRI environment lighting with
//! importance sampling and multiple importance sampling, point and spot
//! lights, and a path tracer that writes, beside the image, the exact
//! per-pixel fraction of each material seen on the main object.

#![warn(missing_docs)]

pub mod bsdf;
pub mod bvh;
pub mod cache;
pub mod camera;
mod content;
pub mod denoise;
pub mod environment;
pub mod hdr_io;
pub mod integrator;
pub mod math;
pub mod mesh;
pub mod mesh_io;
pub mod microfacet;
pub mod primitives;
pub mod sampling;
pub mod scene;
pub mod shading;
pub mod texture;

pub use integrator::{render, tone_map, Rendered};
pub use math::{Aabb, Frame, Ray, Transform, Vec3};
pub use mesh::{Mesh, UvProjection};
pub use scene::{LoadedScene, SceneDescription, SceneError};
