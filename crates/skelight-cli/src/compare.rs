//! `skelight compare`: equal-time runs of several estimators against a reference, error
//! after every pass, and a report: CSV/JSON curves, log-log plots (SVG and PNG), final
//! images with zoomed insets, false-colour errors, time-to-error speed-ups, one HTML page.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result};
use skelight::color::{rgb, Rgb};
use skelight::eval;
use skelight::imageio::Image;

pub use skelight::compare::{metric, run_with, time_to_error, Point, Series};

pub struct Study {
    pub scene_label: String,
    pub reference_label: String,
    pub time: Duration,
    pub every: Duration,
    pub seed: u64,
    pub threads: usize,
    pub series: Vec<Series>,
}

const COLORS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"];

fn color_rgb(i: usize) -> Rgb {
    let h = COLORS[i % COLORS.len()];
    let c = |k: usize| u8::from_str_radix(&h[k..k + 2], 16).unwrap_or(0) as f32 / 255.0;
    rgb(c(1), c(3), c(5))
}

fn log_bounds(series: &[Series], f: impl Fn(&Point) -> f64) -> (f64, f64) {
    let vals: Vec<f64> =
        series.iter().flat_map(|s| s.points.iter().map(&f)).filter(|v| *v > 0.0 && v.is_finite()).collect();
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().cloned().fold(0.0f64, f64::max);
    if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
        let v = if lo.is_finite() { lo } else { 1.0 };
        return ((v / 10.0).log10().floor(), (v * 10.0).log10().ceil());
    }
    (lo.log10().floor(), hi.log10().ceil())
}

/// Log-log error-vs-time plot as SVG.
pub fn plot_svg(series: &[Series]) -> String {
    let (w, h, m) = (640.0, 420.0, 60.0);
    let (x0, x1) = log_bounds(series, |p| p.seconds);
    let (y0, y1) = log_bounds(series, metric);
    let sx = |v: f64| m + (v.log10() - x0) / (x1 - x0) * (w - 1.5 * m);
    let sy = |v: f64| h - m - (v.log10() - y0) / (y1 - y0) * (h - 1.7 * m);
    let mut s = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12"><rect width="100%" height="100%" fill="white"/>"#
    );
    for e in x0 as i32..=x1 as i32 {
        let x = sx(10f64.powi(e));
        let _ = write!(
            s,
            r##"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">1e{e}</text>"##,
            sy(10f64.powf(y1)),
            sy(10f64.powf(y0)),
            h - m + 18.0
        );
    }
    for e in y0 as i32..=y1 as i32 {
        let y = sy(10f64.powi(e));
        let _ = write!(
            s,
            r##"<line x1="{m}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">1e{e}</text>"##,
            w - 0.5 * m,
            m - 6.0,
            y + 4.0
        );
    }
    let _ = write!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">time (s)</text><text x="14" y="{:.1}" transform="rotate(-90 14 {:.1})" text-anchor="middle">relMSE (max over RGB)</text>"#,
        w / 2.0,
        h - 12.0,
        h / 2.0,
        h / 2.0
    );
    for (i, se) in series.iter().enumerate() {
        let pts: Vec<String> = se
            .points
            .iter()
            .filter(|p| p.seconds > 0.0 && metric(p) > 0.0)
            .map(|p| format!("{:.1},{:.1}", sx(p.seconds), sy(metric(p))))
            .collect();
        let c = COLORS[i % COLORS.len()];
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{c}" stroke-width="2" points="{}"/><rect x="{:.1}" y="{:.1}" width="14" height="4" fill="{c}"/><text x="{:.1}" y="{:.1}">{}</text>"#,
            pts.join(" "),
            w - 1.4 * m - 60.0,
            m + 18.0 * i as f64 - 4.0,
            w - 1.4 * m - 40.0,
            m + 18.0 * i as f64,
            se.name
        );
    }
    s.push_str("</svg>");
    s
}

/// The same plot rasterised (curves and grid; the SVG carries the labels).
pub fn plot_png(series: &[Series]) -> Image {
    let (w, h, m) = (640usize, 420usize, 60.0f64);
    let mut img = Image { width: w, height: h, pixels: vec![Rgb::WHITE; w * h] };
    let (x0, x1) = log_bounds(series, |p| p.seconds);
    let (y0, y1) = log_bounds(series, metric);
    let sx = |v: f64| m + (v.log10() - x0) / (x1 - x0) * (w as f64 - 1.5 * m);
    let sy = |v: f64| h as f64 - m - (v.log10() - y0) / (y1 - y0) * (h as f64 - 1.7 * m);
    let line = |img: &mut Image, (ax, ay): (f64, f64), (bx, by): (f64, f64), c: Rgb| {
        let n = ((bx - ax).abs().max((by - ay).abs()) as usize).max(1);
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = ((ax + t * (bx - ax)).round() as i64, (ay + t * (by - ay)).round() as i64);
            if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                img.pixels[y as usize * w + x as usize] = c;
            }
        }
    };
    let grey = Rgb::splat(0.85);
    for e in x0 as i32..=x1 as i32 {
        let x = sx(10f64.powi(e));
        line(&mut img, (x, sy(10f64.powf(y1))), (x, sy(10f64.powf(y0))), grey);
    }
    for e in y0 as i32..=y1 as i32 {
        let y = sy(10f64.powi(e));
        line(&mut img, (m, y), (w as f64 - 0.5 * m, y), grey);
    }
    for (i, se) in series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = se
            .points
            .iter()
            .filter(|p| p.seconds > 0.0 && metric(p) > 0.0)
            .map(|p| (sx(p.seconds), sy(metric(p))))
            .collect();
        for pair in pts.windows(2) {
            for d in [-0.5, 0.0, 0.5] {
                line(&mut img, (pair[0].0, pair[0].1 + d), (pair[1].0, pair[1].1 + d), color_rgb(i));
            }
        }
        // Legend swatch.
        let y = m + 18.0 * i as f64;
        line(&mut img, (w as f64 - 1.4 * m - 60.0, y), (w as f64 - 1.4 * m - 46.0, y), color_rgb(i));
    }
    img
}

/// Time each estimator needs to reach one target error, and its speed-up over the first.
pub struct TargetRow {
    pub target: f64,
    pub times: Vec<Option<f64>>,
    pub speedups: Vec<Option<f64>>,
}

/// Targets: the first estimator's final error ×4, ×2, ×1; speed-up = its time / theirs.
pub fn speedups(series: &[Series]) -> Vec<TargetRow> {
    let Some(final_err) = series.first().and_then(|s| s.points.last()).map(metric) else { return Vec::new() };
    [4.0, 2.0, 1.0]
        .iter()
        .map(|k| {
            let target = final_err * k;
            let times: Vec<Option<f64>> = series.iter().map(|s| time_to_error(&s.points, target)).collect();
            let base = times[0];
            let speedups = times
                .iter()
                .map(|t| match (base, t) {
                    (Some(b), Some(t)) if *t > 0.0 => Some(b / t),
                    _ => None,
                })
                .collect();
            TargetRow { target, times, speedups }
        })
        .collect()
}

pub fn csv(series: &[Series]) -> String {
    let mut s =
        String::from("integrator,iteration,spp,seconds,mae,rmse,relmse,nrmse,mae_lum,rmse_lum,relmse_lum,nrmse_lum\n");
    for se in series {
        for p in &se.points {
            let m = &p.metrics;
            let _ = writeln!(
                s,
                "{},{},{},{:.6},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e}",
                se.name,
                p.iteration,
                p.spp,
                p.seconds,
                m.mae,
                m.rmse,
                m.relmse,
                m.nrmse,
                m.mae_lum,
                m.rmse_lum,
                m.relmse_lum,
                m.nrmse_lum
            );
        }
    }
    s
}

/// `errors.json`: the study's settings and every estimator's error curve (non-finite
/// values as `null`).
pub fn json(study: &Study) -> String {
    #[derive(serde::Serialize)]
    struct Point {
        iteration: usize,
        spp: u32,
        seconds: f64,
        mae: f64,
        rmse: f64,
        relmse: f64,
        nrmse: f64,
    }
    #[derive(serde::Serialize)]
    struct Series<'a> {
        integrator: &'a str,
        points: Vec<Point>,
    }
    #[derive(serde::Serialize)]
    struct Errors<'a> {
        scene: &'a str,
        reference: &'a str,
        time_s: f64,
        seed: u64,
        threads: usize,
        series: Vec<Series<'a>>,
    }
    let series = study
        .series
        .iter()
        .map(|se| Series {
            integrator: &se.name,
            points: se
                .points
                .iter()
                .map(|p| Point {
                    iteration: p.iteration,
                    spp: p.spp,
                    seconds: p.seconds,
                    mae: p.metrics.mae,
                    rmse: p.metrics.rmse,
                    relmse: p.metrics.relmse,
                    nrmse: p.metrics.nrmse,
                })
                .collect(),
        })
        .collect();
    let errors = Errors {
        scene: &study.scene_label,
        reference: &study.reference_label,
        time_s: study.time.as_secs_f64(),
        seed: study.seed,
        threads: study.threads,
        series,
    };
    serde_json::to_string_pretty(&errors).expect("plain values serialize") + "\n"
}

/// Region (x, y, size) around the block where the first estimator errs most.
fn inset_region(img: &Image, reference: &Image) -> (usize, usize, usize) {
    let size = (img.width.min(img.height) / 4).max(4);
    let mut best = (0.0f32, 0usize, 0usize);
    for by in (0..img.height.saturating_sub(size)).step_by(size / 2) {
        for bx in (0..img.width.saturating_sub(size)).step_by(size / 2) {
            let mut e = 0.0;
            for y in by..by + size {
                for x in bx..bx + size {
                    e += (img.get(x, y).luminance() - reference.get(x, y).luminance()).abs();
                }
            }
            if e > best.0 {
                best = (e, bx, by);
            }
        }
    }
    (best.1, best.2, size)
}

/// Final images side by side (reference last), each with a 2× inset of the worst region.
pub fn side_by_side(series: &[Series], reference: &Image) -> Image {
    let (w, h) = (reference.width, reference.height);
    let images: Vec<&Image> = series.iter().map(|s| &s.image).chain(std::iter::once(reference)).collect();
    let (ix, iy, size) = inset_region(&series[0].image, reference);
    let inset = (2 * size).min(w);
    let (cw, ch) = (w + 4, h + inset + 8);
    let mut out = Image { width: cw * images.len(), height: ch, pixels: vec![Rgb::WHITE; cw * images.len() * ch] };
    for (k, img) in images.iter().enumerate() {
        let ox = k * cw;
        for y in 0..h {
            for x in 0..w {
                out.pixels[y * out.width + ox + x] = img.get(x, y);
            }
        }
        for y in 0..inset {
            for x in 0..inset {
                let (sx, sy) = ((ix + x * size / inset).min(w - 1), (iy + y * size / inset).min(h - 1));
                out.pixels[(h + 4 + y) * out.width + ox + x] = img.get(sx, sy);
            }
        }
    }
    out
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    format!("{cpu}, {cores} hardware threads, {}", std::env::consts::OS)
}

fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len() * 4 / 3 + 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            out.push(if i <= c.len() { T[(n >> (18 - 6 * i) & 63) as usize] as char } else { '=' });
        }
    }
    out
}

fn img_tag(img: &Image, alt: &str) -> Result<String> {
    let png = img.to_png_bytes(0.0).map_err(anyhow::Error::msg)?;
    Ok(format!(r#"<img alt="{alt}" src="data:image/png;base64,{}"/>"#, base64(&png)))
}

/// A series' name as a file name: every character other than letters, digits and `.:=,+-#`
/// becomes `_` (a parameter may be a path: `portalpt:portals=scenes/portals/door.json`;
/// `pt#2` names a study's second `pt`).
fn file_stem(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || ".:=,+-#".contains(c) { c } else { '_' }).collect()
}

/// Writes every output of the study into `dir`.
pub fn write_report(study: &Study, reference: &Image, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let write = |name: &str, text: &str| crate::write_text(&dir.join(name), text);
    write("errors.csv", &csv(&study.series))?;
    write("errors.json", &json(study))?;
    let svg = plot_svg(&study.series);
    write("error_vs_time.svg", &svg)?;
    plot_png(&study.series).save_png(&dir.join("error_vs_time.png"), 0.0)?;
    let mut errors = Vec::new();
    for s in &study.series {
        let stem = file_stem(&s.name);
        s.image.save_exr_with(
            &dir.join(format!("{stem}.exr")),
            &[("skelight.spp", s.points.last().map(|p| p.spp as f64).unwrap_or(0.0))],
        )?;
        s.image.save_png(&dir.join(format!("{stem}.png")), 0.0)?;
        let e = eval::error_image(&s.image, reference, 0.5)?;
        e.save_png(&dir.join(format!("{stem}_error.png")), 0.0)?;
        errors.push(e);
    }
    let sbs = side_by_side(&study.series, reference);
    sbs.save_png(&dir.join("side_by_side.png"), 0.0)?;

    let ups = speedups(&study.series);
    let mut table = String::from("target relMSE");
    for s in &study.series {
        let _ = write!(table, ",{} time (s),{} speed-up", s.name, s.name);
    }
    table.push('\n');
    let fmt =
        |v: Option<f64>, digits: usize| v.map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "not reached".into());
    for TargetRow { target, times, speedups: sp } in &ups {
        let _ = write!(table, "{target:.4e}");
        for (t, u) in times.iter().zip(sp) {
            let _ = write!(table, ",{},{}", fmt(*t, 3), fmt(*u, 2));
        }
        table.push('\n');
    }
    write("time_to_error.csv", &table)?;

    let mut html = String::from("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>skelight comparison</title><style>body{font-family:sans-serif;margin:2em}td,th{padding:4px 10px;border-bottom:1px solid #ddd;text-align:right}img{image-rendering:pixelated;margin:4px}</style></head><body>");
    let _ = write!(html, "<h1>Equal-time comparison</h1><p>Scene <code>{}</code>, reference <code>{}</code>, {:.1} s per estimator, error measured every {}, seed {}, {} threads.<br>Machine: {}. skelight {} (git {}).</p>", study.scene_label, study.reference_label, study.time.as_secs_f64(), if study.every.is_zero() { "pass".to_string() } else { format!("{:.1} s", study.every.as_secs_f64()) }, study.seed, if study.threads == 0 { "all".into() } else { study.threads.to_string() }, machine(), env!("CARGO_PKG_VERSION"), option_env!("SKELIGHT_GIT_REV").unwrap_or("unknown"));
    html.push_str("<h2>Error against time</h2>");
    html.push_str(&svg);
    html.push_str("<h2>Final errors</h2><table><tr><th>estimator</th><th>spp</th><th>seconds</th><th>of which preparation</th><th>MAE</th><th>RMSE</th><th>relMSE</th><th>NRMSE</th></tr>");
    for s in &study.series {
        if let Some(p) = s.points.last() {
            let m = &p.metrics;
            let _ = write!(html, "<tr><td>{}</td><td>{}</td><td>{:.2}</td><td>{:.2}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.4e}</td></tr>", s.name, p.spp, p.seconds, s.preparation, m.mae, m.rmse, m.relmse, m.nrmse);
        }
    }
    html.push_str(
        "</table><h2>Time to error (speed-up relative to the first estimator)</h2><table><tr><th>target relMSE</th>",
    );
    for s in &study.series {
        let _ = write!(html, "<th>{} time (s)</th><th>{} speed-up</th>", s.name, s.name);
    }
    html.push_str("</tr>");
    for TargetRow { target, times, speedups: sp } in &ups {
        let _ = write!(html, "<tr><td>{target:.3e}</td>");
        for (t, u) in times.iter().zip(sp) {
            let _ = write!(html, "<td>{}</td><td>{}</td>", fmt(*t, 3), fmt(*u, 2));
        }
        html.push_str("</tr>");
    }
    html.push_str(
        "</table><h2>Images (estimators, then the reference; below each, the region of largest error ×2)</h2>",
    );
    html.push_str(&img_tag(&sbs, "side by side")?);
    html.push_str("<h2>Relative error (luminance; black 0 → red ≥ 50 %)</h2>");
    for (s, e) in study.series.iter().zip(&errors) {
        let _ = write!(
            html,
            "<figure style=\"display:inline-block\">{}<figcaption>{}</figcaption></figure>",
            img_tag(e, &s.name)?,
            s.name
        );
    }
    html.push_str("</body></html>\n");
    write("report.html", &html)
}

#[cfg(test)]
mod tests {
    use super::file_stem;

    /// A parameter holding a path must not put the series' files in folders of that path.
    #[test]
    fn series_names_become_file_names() {
        assert_eq!(file_stem("portalpt:portals=/tmp/p/door.json"), "portalpt:portals=_tmp_p_door.json");
        assert_eq!(file_stem("skelpt:c_skel=0.25:adaptive=false"), "skelpt:c_skel=0.25:adaptive=false");
        assert_eq!(file_stem("pt#2"), "pt#2");
    }
}
