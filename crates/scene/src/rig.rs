//! Multi-view rigs: N cameras on a Fibonacci sphere looking at the origin, with one fixed light
//! or a light attached to each camera.
//!
//! SKELETON: helper H3 owns this file.
