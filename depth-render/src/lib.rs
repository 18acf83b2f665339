//! CPU BVH depth rendering of triangle meshes. Filled by its own issue.
