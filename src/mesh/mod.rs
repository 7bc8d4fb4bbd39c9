//! Meshes out of object fields: marching cubes, cleanup, and glTF/PLY/OBJ writers.

pub mod marching;
mod tables;
