//! Skinned multiresolution characters (ASLOD section 5): rigid and deformable regions,
//! shortest-path two-bone weights, linear blend skinning of cached vertices.
