//! The procedural mannequin: a skinned, animated humanoid written as a `.glb`.
