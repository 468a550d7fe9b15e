//! `voxcast bench`: methods compared on one scene (being written).
