//! pneuflex-pneumatics (being built).
