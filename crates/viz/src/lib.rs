//! pneuflex-viz (being built).
