//! Solid procedural textures (section 4.3.1): hashing, Voronoi, noise, the pattern tree.
