//! Procedural datasets of the rendering pipeline (filled in below).
