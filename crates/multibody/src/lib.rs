//! pneuflex-multibody (being built).
