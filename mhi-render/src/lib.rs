//! Rendering of multiple homography images (not implemented yet: issue #4).
