//! volpath
