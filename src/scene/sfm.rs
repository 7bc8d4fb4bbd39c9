//! `objnerf sfm`: give a scene 2D-3D tracks with the real COLMAP.
