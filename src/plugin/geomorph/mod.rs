//! Geomorphs in the plugin: the morphs of region models ([`RegionGeomorphs`]), one output
//! path for them and for view-dependent levels ([`MorphOutput`]: what moves and how it
//! reaches the GPU), and the material whose vertex shaders interpolate them
//! ([`GeomorphMaterial`]; the shaders live beside it).

mod material;
mod output;
mod regions;

pub use material::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, ATTRIBUTE_MORPH_TANGENT_FROM,
    ATTRIBUTE_MORPH_UV_FROM, GeomorphExtension, GeomorphMaterial, GeomorphMaterialPlugin,
    GpuGeomorph,
};
pub(crate) use output::{Clock, LevelMorphs, MorphChange, MorphOutput, MorphTarget};
pub(crate) use regions::{RegionGeomorphs, RegionGrant};
