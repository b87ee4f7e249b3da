//! Line charts as PNG for the benchmark report: axes with ticks, one line
//! per series, a legend, and text in a built-in 5x7 pixel font, so the
//! report needs no font files and no plotting dependency.

use std::fmt::Write as _;

/// One line of a chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points, drawn in order.
    pub points: Vec<(f64, f64)>,
}

/// A chart: title, axis labels and series.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// Title, above the plot.
    pub title: String,
    /// Label under the x axis.
    pub x_label: String,
    /// Label over the y axis.
    pub y_label: String,
    /// Logarithmic x axis (sphere counts, sizes, distances).
    pub log_x: bool,
    /// The lines.
    pub series: Vec<Series>,
}

/// Line colours, in series order (then repeating).
const COLOURS: [[u8; 3]; 6] = [[31, 119, 180], [214, 39, 40], [44, 160, 44], [255, 127, 14], [148, 103, 189], [23, 190, 207]];

/// 5x7 glyphs, one row per byte (bit 4 is the leftmost column).
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '²' => [0x0C, 0x02, 0x04, 0x08, 0x0E, 0, 0],
        '×' => [0, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0],
        _ => [0; 7],
    }
}

struct Canvas {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let k = (y as usize * self.width as usize + x as usize) * 3;
            self.rgb[k..k + 3].copy_from_slice(&c);
        }
    }

    /// A line `thick` pixels wide (Bresenham, stamped).
    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3], thick: i64) {
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i64;
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = ((x0 + (x1 - x0) * t).round() as i64, (y0 + (y1 - y0) * t).round() as i64);
            for dy in 0..thick {
                for dx in 0..thick {
                    self.put(x + dx - thick / 2, y + dy - thick / 2, c);
                }
            }
        }
    }

    /// Text at 2x scale with its top-left at (x, y); returns its width.
    fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3]) -> i64 {
        const SCALE: i64 = 2;
        for (k, ch) in s.chars().enumerate() {
            let rows = glyph(ch);
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for dy in 0..SCALE {
                            for dx in 0..SCALE {
                                self.put(x + (k as i64 * 6 + col) * SCALE + dx, y + r as i64 * SCALE + dy, c);
                            }
                        }
                    }
                }
            }
        }
        text_width(s)
    }
}

fn text_width(s: &str) -> i64 {
    s.chars().count() as i64 * 12
}

/// A short label for an axis value.
fn tick_label(v: f64) -> String {
    let mut s = String::new();
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 0.001) {
        let _ = write!(s, "{v:.0E}");
    } else if v.fract() == 0.0 {
        let _ = write!(s, "{v:.0}");
    } else {
        let digits = if v.abs() >= 1.0 { 2 } else { 3 };
        let _ = write!(s, "{v:.digits$}");
    }
    s
}

/// The title at the top left from `left`; one too wide for the canvas breaks
/// before its last parenthesis.
fn draw_title(cv: &mut Canvas, title: &str, left: i64, ink: [u8; 3]) {
    let fits = |t: &str| left + text_width(t) <= i64::from(cv.width) - 4;
    match title.rfind(" (").filter(|_| !fits(title)) {
        Some(k) => {
            cv.text(left, 4, &title[..k], ink);
            cv.text(left, 22, title[k..].trim_start(), ink);
        }
        None => {
            cv.text(left, 12, title, ink);
        }
    }
}

/// Round y ticks up to `y_max`: a step of 1, 2 or 5 times a power of ten,
/// and how many steps (five or fewer).
fn y_ticks(y_max: f64) -> (f64, u32) {
    let magnitude = 10f64.powf((y_max / 5.0).log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * magnitude).find(|s| y_max / s <= 5.0).unwrap_or(10.0 * magnitude);
    (step, (y_max / step).ceil().max(1.0) as u32)
}

/// The chart as a PNG of `width` x `height` pixels. Points that are not
/// finite (or not positive on a log axis) are left out.
#[must_use]
pub fn render_png(chart: &Chart, width: u32, height: u32) -> Vec<u8> {
    const INK: [u8; 3] = [30, 30, 30];
    const GRID: [u8; 3] = [225, 225, 225];
    let mut cv = Canvas { width, height, rgb: vec![255; (width * height * 3) as usize] };
    let fx = |x: f64| if chart.log_x { x.log10() } else { x };
    let usable = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && (!chart.log_x || x > 0.0);
    let points: Vec<(f64, f64)> = chart.series.iter().flat_map(|s| s.points.iter().copied().filter(usable)).collect();
    let (left, right, top, bottom) = (90i64, i64::from(width) - 200, 50i64, i64::from(height) - 60);
    draw_title(&mut cv, &chart.title, left, INK);
    cv.text(left - 60, top - 24, &chart.y_label, INK);
    let xl = chart.x_label.as_str();
    cv.text((left + right) / 2 - text_width(xl) / 2, bottom + 34, xl, INK);
    let (mut x0, mut x1) = points.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(fx(p.0)), b.max(fx(p.0))));
    let y1 = points.iter().fold(f64::MIN, |a, p| a.max(p.1));
    if points.is_empty() {
        (x0, x1) = (0.0, 1.0);
    }
    if x1 - x0 < 1e-12 {
        (x0, x1) = (x0 - 0.5, x1 + 0.5);
    }
    // Round y ticks: a step of 1, 2 or 5 times a power of ten, five or fewer of them.
    let y_max = if points.is_empty() || y1 <= 0.0 { 1.0 } else { y1 };
    let (step, ticks) = y_ticks(y_max);
    let y1 = step * f64::from(ticks);
    let (y0, xs, ys) = (0.0, (right - left) as f64 / (x1 - x0), (bottom - top) as f64 / y1);
    let px = |x: f64| left as f64 + (fx(x) - x0) * xs;
    let py = |y: f64| bottom as f64 - (y - y0) * ys;
    // Grid and ticks: five on y; the data's own x values (or five) on x.
    for k in 0..=ticks {
        let v = step * f64::from(k);
        let y = py(v);
        cv.line((left as f64, y), (right as f64, y), GRID, 1);
        let label = tick_label(v);
        cv.text(left - 8 - text_width(&label), y as i64 - 7, &label, INK);
    }
    let mut xticks: Vec<f64> = points.iter().map(|p| p.0).collect();
    xticks.sort_by(f64::total_cmp);
    xticks.dedup();
    if xticks.len() > 8 || xticks.is_empty() {
        xticks = (0..=4)
            .map(|k| {
                let t = x0 + (x1 - x0) * f64::from(k) / 4.0;
                if chart.log_x { 10f64.powf(t) } else { t }
            })
            .collect();
    }
    for v in xticks {
        let x = px(v);
        cv.line((x, top as f64), (x, bottom as f64), GRID, 1);
        let label = tick_label(v);
        cv.text(x as i64 - text_width(&label) / 2, bottom + 8, &label, INK);
    }
    cv.line((left as f64, bottom as f64), (right as f64, bottom as f64), INK, 2);
    cv.line((left as f64, top as f64), (left as f64, bottom as f64), INK, 2);
    for (k, s) in chart.series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(usable).map(|(x, y)| (px(x), py(y))).collect();
        for w in pts.windows(2) {
            cv.line(w[0], w[1], colour, 3);
        }
        for &(x, y) in &pts {
            cv.line((x - 3.0, y), (x + 3.0, y), colour, 3);
        }
        let ly = top + 10 + k as i64 * 24;
        cv.line(((right + 16) as f64, (ly + 7) as f64), ((right + 40) as f64, (ly + 7) as f64), colour, 4);
        cv.text(right + 48, ly, &s.name, INK);
    }
    let mut png = Vec::new();
    let img = image::RgbImage::from_raw(width, height, cv.rgb).unwrap_or_else(|| image::RgbImage::new(width, height));
    // Encoding an in-memory RGB image into a Vec cannot fail.
    let _ = image::DynamicImage::ImageRgb8(img).write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png);
    png
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> Chart {
        Chart {
            title: "GPU ms against spheres".into(),
            x_label: "spheres".into(),
            y_label: "ms".into(),
            log_x: true,
            series: vec![
                Series { name: "depth".into(), points: vec![(128.0, 0.5), (1024.0, 1.0), (16384.0, 4.0)] },
                Series { name: "points".into(), points: vec![(128.0, 0.2), (1024.0, 2.0), (16384.0, f64::NAN)] },
            ],
        }
    }

    #[test]
    fn a_chart_is_a_png_with_its_lines_in_their_colours() {
        let png = render_png(&chart(), 640, 400);
        let img = image::load_from_memory(&png).expect("a PNG").to_rgb8();
        assert_eq!(img.dimensions(), (640, 400));
        let count = |c: [u8; 3]| img.pixels().filter(|p| p.0 == c).count();
        // Each series drew its line (and legend swatch); text and axes are dark.
        assert!(count(COLOURS[0]) > 300, "{} pixels of the first series", count(COLOURS[0]));
        assert!(count(COLOURS[1]) > 150, "{} pixels of the second series", count(COLOURS[1]));
        assert!(count([30, 30, 30]) > 500, "axes and text");
        // The first series rises to the right: its rightmost pixel is higher (smaller y) than its leftmost.
        let xs: Vec<(u32, u32)> = img.enumerate_pixels().filter(|p| p.2.0 == COLOURS[0] && p.0 < 440).map(|p| (p.0, p.1)).collect();
        let leftmost = xs.iter().min_by_key(|p| p.0).expect("pixels");
        let rightmost = xs.iter().max_by_key(|p| p.0).expect("pixels");
        assert!(rightmost.1 < leftmost.1, "{leftmost:?} .. {rightmost:?}");
    }

    #[test]
    fn a_long_title_breaks_into_two_lines_inside_the_image() {
        let mut c = chart();
        c.title = "Render ms per pass at 1920x1080 against camera distance (software: ratios only)".into();
        let img = image::load_from_memory(&render_png(&c, 960, 540)).expect("PNG").to_rgb8();
        // Ink in the title band on two separate text rows, none in the last columns.
        let ink_in_rows = |y0: u32, y1: u32| (y0..y1).any(|y| (90..960).any(|x| img.get_pixel(x, y).0 == [30, 30, 30]));
        assert!(ink_in_rows(4, 18) && ink_in_rows(22, 36), "the title is not on two lines");
        assert!((0..40).all(|y| (950..960).all(|x| img.get_pixel(x, y).0 != [30, 30, 30])), "the title runs off the image");
    }

    #[test]
    fn empty_and_degenerate_charts_still_draw() {
        let mut c = chart();
        c.series.clear();
        assert!(image::load_from_memory(&render_png(&c, 320, 200)).is_ok());
        c.series = vec![Series { name: "one".into(), points: vec![(5.0, 0.0)] }];
        c.log_x = false;
        assert!(image::load_from_memory(&render_png(&c, 320, 200)).is_ok());
        assert_eq!(tick_label(16384.0), "16384");
        assert_eq!(tick_label(2.5e6), "2E6");
        assert_eq!(tick_label(0.25), "0.250");
        assert_eq!(tick_label(4.0), "4");
    }
}
