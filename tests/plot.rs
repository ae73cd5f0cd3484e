//! `afe plot`: a figure for every request, one panel per output signal, each panel with
//! content; SVG too; bad outputs and times are clear errors.
#![cfg(feature = "plot")]

use crate::common;

use std::collections::HashSet;
use std::path::Path;

use common::{afe, assert_clear_error, tmp};

const EXAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/example_binaural.wav");
/// `afe plot`'s default figure width and panel height, in pixels.
const WIDTH: u32 = 1000;
const PANEL: u32 = 230;

/// Width, height and RGB pixels of a PNG.
fn decode(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).expect("figure written"));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("pixels");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = buf[..info.buffer_size()]
        .chunks_exact(3)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width, info.height, pixels)
}

/// The number of signals `afe extract` writes for `request` on the example.
fn outputs(request: &str) -> usize {
    let npz = tmp(&format!("{request}.npz"));
    let out = afe(&[
        "extract",
        EXAMPLE,
        "-r",
        request,
        "-o",
        npz.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    common::npz_arrays(&npz).len()
}

#[test]
fn every_request_gets_a_panel_per_signal_each_with_content() {
    for def in afe::requests() {
        let png = tmp(&format!("{}.png", def.name));
        let out = afe(&[
            "plot",
            EXAMPLE,
            "-r",
            def.name,
            "-o",
            png.to_str().expect("path"),
        ]);
        assert!(
            out.status.success(),
            "{}: {}",
            def.name,
            String::from_utf8_lossy(&out.stderr)
        );
        let (w, h, pixels) = decode(&png);
        let panels = outputs(def.name);
        assert_eq!((w, h), (WIDTH, PANEL * panels as u32), "{}", def.name);
        for (p, panel) in pixels.chunks_exact((WIDTH * PANEL) as usize).enumerate() {
            // the plot, left of the colour bar (the right 110 pixels)
            let strip: Vec<[u8; 3]> = panel
                .chunks_exact(WIDTH as usize)
                .flat_map(|row| row[..(WIDTH - 110) as usize].iter().copied())
                .collect();
            let colours: HashSet<[u8; 3]> = strip.iter().copied().collect();
            let inked = strip.iter().filter(|c| **c != [255, 255, 255]).count();
            let chromatic = strip
                .iter()
                .filter(|c| c[0] != c[1] || c[1] != c[2])
                .count();
            // axes and text alone ink about 2% of a panel, in greys: an image fills most
            // of it (a mask in greys too), a line draws in colour (pitch: the voiced
            // frames of one second of speech only)
            assert!(
                colours.len() >= 12 && (inked * 4 >= strip.len() || chromatic >= 100),
                "{} panel {p}: {} colours, {inked} inked and {chromatic} coloured pixels",
                def.name,
                colours.len()
            );
        }
    }
}

#[test]
fn svg_figures_draw_the_same_panels_and_bad_outputs_are_clear_errors() {
    let svg = tmp("cues.svg");
    let out = afe(&[
        "plot",
        EXAMPLE,
        "-r",
        "ratemap,crosscorrelation",
        "--at",
        "0.5",
        "-o",
        svg.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&svg).expect("svg written");
    assert!(text.starts_with("<svg"), "{}", &text[..40.min(text.len())]);
    for title in [
        "ratemap_left",
        "ratemap_right",
        "crosscorrelation_mono at 0.50",
    ] {
        assert!(text.contains(title), "{title} missing");
    }
    assert!(
        text.matches("<rect").count() > 1000,
        "images are drawn as cells"
    );

    let bmp = tmp("fig.bmp");
    let out = afe(&[
        "plot",
        EXAMPLE,
        "-r",
        "ild",
        "-o",
        bmp.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "name it .png or .svg", &bmp);
    let late = tmp("late.png");
    let out = afe(&[
        "plot",
        EXAMPLE,
        "-r",
        "crosscorrelation",
        "--at",
        "7",
        "-o",
        late.to_str().expect("path"),
    ]);
    assert_clear_error(&out, "--at 7 s is outside crosscorrelation", &late);
}

/// The colours of panel `p`'s plot area (left of the colour bar) in a figure of `pixels`.
fn plot_area(pixels: &[[u8; 3]], p: usize) -> Vec<[u8; 3]> {
    pixels
        .chunks_exact((WIDTH * PANEL) as usize)
        .nth(p)
        .expect("the panel")
        .chunks_exact(WIDTH as usize)
        .flat_map(|row| row[..(WIDTH - 110) as usize].iter().copied())
        .collect()
}

#[test]
fn audio_rate_channels_are_stacked_waveforms_unless_images_are_asked() {
    let draw = |extra: &[&str]| {
        let png = tmp(&format!("ihc{}.png", extra.len()));
        let mut args = vec![
            "plot",
            EXAMPLE,
            "-r",
            "innerhaircell",
            "-p",
            "fb_nChannels=16",
        ];
        args.extend(extra);
        args.extend(["-o", png.to_str().expect("path")]);
        let out = afe(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        decode(&png).2
    };
    let chromatic = |area: &[[u8; 3]]| -> HashSet<[u8; 3]> {
        area.iter()
            .copied()
            .filter(|c| c[0] != c[1] || c[1] != c[2])
            .collect()
    };
    // waveforms: traces in blue (its blends with the white background at their
    // edges), many pixels of it (the envelope of 44 100 samples in each of 16
    // channels), no colour map
    let waves = plot_area(&draw(&[]), 0);
    let traces = waves.iter().filter(|c| **c == [0, 0, 255]).count();
    let blue_or_blend = |c: &[u8; 3]| c[0] == c[1] && c[2] == 255;
    assert!(chromatic(&waves).iter().all(blue_or_blend));
    assert!(traces > 10_000, "{traces} trace pixels");
    // images: the colour map's many colours
    let image = plot_area(&draw(&["--images"]), 0);
    let mapped = chromatic(&image);
    assert!(mapped.iter().filter(|c| !blue_or_blend(c)).count() > 50);
}
