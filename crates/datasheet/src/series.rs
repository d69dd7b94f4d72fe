//! Standard cylinder sizes: the bore-and-rod pairs of ISO 15552 (profile and tie-rod cylinders, 32–320 mm)
//! and ISO 6432 (round mini cylinders, 8–25 mm), with the port thread each size usually carries. The port
//! decides the tubing bore a fitter uses, and with it the dead volume when a datasheet does not give one.

/// One standard size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Size {
    /// The standard it belongs to.
    pub standard: &'static str,
    /// Bore, mm.
    pub bore_mm: f64,
    /// Piston rod, mm.
    pub rod_mm: f64,
    /// Port thread.
    pub port: &'static str,
    /// Inner diameter of the tube a fitter puts on this port, mm (M5: 4/2.5 mm, G1/8: 6/4, G1/4: 8/6,
    /// G3/8: 10/8, G1/2: 12/9, G3/4: 16/12, G1: 20/16 — outer/inner, the common push-in sizes).
    pub tube_inner_mm: f64,
}

const fn size(
    standard: &'static str,
    bore_mm: f64,
    rod_mm: f64,
    port: &'static str,
    tube_inner_mm: f64,
) -> Size {
    Size {
        standard,
        bore_mm,
        rod_mm,
        port,
        tube_inner_mm,
    }
}

/// ISO 6432 then ISO 15552, by bore.
pub const SIZES: [Size; 17] = [
    size("ISO 6432", 8.0, 4.0, "M5", 2.5),
    size("ISO 6432", 10.0, 4.0, "M5", 2.5),
    size("ISO 6432", 12.0, 6.0, "M5", 2.5),
    size("ISO 6432", 16.0, 6.0, "M5", 2.5),
    size("ISO 6432", 20.0, 8.0, "G1/8", 4.0),
    size("ISO 6432", 25.0, 10.0, "G1/8", 4.0),
    size("ISO 15552", 32.0, 12.0, "G1/8", 4.0),
    size("ISO 15552", 40.0, 16.0, "G1/4", 6.0),
    size("ISO 15552", 50.0, 20.0, "G1/4", 6.0),
    size("ISO 15552", 63.0, 20.0, "G3/8", 8.0),
    size("ISO 15552", 80.0, 25.0, "G3/8", 8.0),
    size("ISO 15552", 100.0, 25.0, "G1/2", 9.0),
    size("ISO 15552", 125.0, 32.0, "G1/2", 9.0),
    size("ISO 15552", 160.0, 40.0, "G3/4", 12.0),
    size("ISO 15552", 200.0, 40.0, "G3/4", 12.0),
    size("ISO 15552", 250.0, 50.0, "G1", 16.0),
    size("ISO 15552", 320.0, 63.0, "G1", 16.0),
];

/// The standard size of this bore, if it is one.
pub fn by_bore(bore_mm: f64) -> Option<Size> {
    SIZES
        .iter()
        .copied()
        .find(|s| (s.bore_mm - bore_mm).abs() < 1e-9)
}

/// The standard size nearest this bore (for the port and rod of a non-standard bore).
pub fn nearest(bore_mm: f64) -> Size {
    *SIZES
        .iter()
        .min_by(|a, b| {
            (a.bore_mm - bore_mm)
                .abs()
                .total_cmp(&(b.bore_mm - bore_mm).abs())
        })
        .expect("the series is not empty")
}

/// The bores of the series, for messages.
pub fn bores() -> String {
    SIZES
        .iter()
        .map(|s| format!("{}", s.bore_mm))
        .collect::<Vec<_>>()
        .join(", ")
}
