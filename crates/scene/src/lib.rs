//! pneuflex-scene (being built).
