//! pneuflex-rig (being built).
