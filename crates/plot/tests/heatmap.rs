//! A heatmap with every cell state: a value, no value (×), an infinite settling time (∞), a flagged run (†)
//! and a fragile value (*); each state present gets its line of legend under the map, with room made for it.

use pneuflex_plot::{Heatmap, write_heatmap};

/// Width and height of a PNG, from its IHDR chunk.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

fn draw(cells: &[Option<f64>], marked: &[bool], flagged: &[bool]) -> (u32, u32) {
    let path = std::env::temp_dir().join(format!(
        "pneuflex-heatmap-{}-{}.png",
        std::process::id(),
        cells.len()
            + marked.iter().filter(|m| **m).count() * 10
            + flagged.iter().filter(|m| **m).count() * 100
    ));
    let ticks = ["1".to_string(), "2".to_string()];
    write_heatmap(
        &path,
        &Heatmap {
            title: "scene, run a: window.rms force error [N]",
            x_label: "environment.stiffness [N/m]",
            x_ticks: &ticks,
            y_label: "runs[*].inner.kp [1/m]",
            y_ticks: &ticks,
            cells,
            marked,
            mark_note: "* fragile",
            flagged,
            flag_note: "† not settled somewhere",
            value_label: "window.rms force error [N]",
            diverging: false,
        },
    )
    .unwrap();
    let size = png_size(&std::fs::read(&path).unwrap());
    let _ = std::fs::remove_file(&path);
    size
}

#[test]
fn every_cell_state_gets_a_legend_line_and_room_under_the_map() {
    let plain = draw(&[Some(1.0), Some(2.0), Some(3.0), Some(4.0)], &[], &[]);
    assert_eq!(plain, (900, 700));
    // ×, ∞, † and *: four lines of 18 px under the map.
    let all = draw(
        &[None, Some(f64::INFINITY), Some(3.0), Some(4.0)],
        &[false, false, false, true],
        &[false, false, true, false],
    );
    assert_eq!(all, (900, 700 + 4 * 18));
    // Only what the map shows is explained.
    let one = draw(&[None, Some(2.0), Some(3.0), Some(4.0)], &[], &[]);
    assert_eq!(one, (900, 700 + 18));
}

#[test]
fn a_path_ending_in_svg_gets_a_vector_heatmap_with_its_legend() {
    let path = std::env::temp_dir().join(format!("pneuflex-heatmap-{}.svg", std::process::id()));
    let ticks = ["1".to_string(), "2".to_string()];
    write_heatmap(
        &path,
        &Heatmap {
            title: "scene, run a: window.settling time [s]",
            x_label: "environment.stiffness [N/m]",
            x_ticks: &ticks,
            y_label: "runs[*].inner.kp [1/m]",
            y_ticks: &ticks,
            cells: &[Some(0.3), Some(f64::INFINITY), None, Some(0.4)],
            marked: &[],
            mark_note: "* fragile",
            flagged: &[false, true, false, false],
            flag_note: "† not settled somewhere",
            value_label: "window.settling time [s]",
            diverging: false,
        },
    )
    .unwrap();
    let svg = std::fs::read_to_string(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    assert!(svg.starts_with("<svg"), "{}", &svg[..60.min(svg.len())]);
    for text in [
        "environment.stiffness [N/m]",
        "grey ×: no value",
        "grey ∞: not settled",
        "† not settled somewhere",
        "∞†",
    ] {
        assert!(svg.contains(text), "{text}");
    }
}
