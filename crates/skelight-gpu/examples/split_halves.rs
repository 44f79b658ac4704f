//! Diagnostic for issue 35's open veach-door bias: renders a scene with GPU ibpt, GPU pt and
//! CPU ibpt (seeds 3 and 4) and prints, for the whole image and for a region (by default the
//! strip at the right edge where the bias shows: columns 29–31 of 32, rows 4–14 of 24,
//! scaled to the size), each ibpt film's camera half (its film with `splat_paths = 0`) and its
//! light-tracing splats. On the same seeds GPU ibpt's camera half over GPU pt is the camera
//! pass's share of the MIS weight.
//!
//! `cargo run --release -p skelight-gpu --example split_halves -- SCENE W H DEPTH GPU_SPP CPU_SPP`
use skelight::film::Film;
use skelight::integrator::{render, RenderOptions};
use skelight::scene::load::load;
use skelight_gpu::{Estimator, GpuRenderer};

fn halves(film: &Film) -> (skelight::imageio::Image, skelight::imageio::Image) {
    let total = film.image();
    let mut cam = film.clone();
    cam.splat_paths = 0;
    (total, cam.image())
}

fn strip(img: &skelight::imageio::Image, w: usize, x0: usize, x1: usize, y0: usize, y1: usize) -> f64 {
    let mut s = 0.0;
    let mut n = 0.0;
    for y in y0..y1 {
        for x in x0..x1 {
            s += img.pixels[y * w + x].mean() as f64;
            n += 1.0;
        }
    }
    s / n
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let (w, h): (usize, usize) = (a[2].parse().unwrap(), a[3].parse().unwrap());
    let mut scene = load(std::path::Path::new(&a[1]), &[]).unwrap();
    scene.set_resolution(w, h);
    scene.settings.max_depth = a[4].parse().unwrap();
    let (gspp, cspp): (u32, u32) = (a[5].parse().unwrap(), a[6].parse().unwrap());
    let (x0, x1, y0, y1) = (w * 29 / 32, w, h * 4 / 24, h * 15 / 24);
    for seed in [3u64, 4] {
        let mut gpu = GpuRenderer::new(&scene, Estimator::Ibpt).unwrap();
        let mut film = Film::new(w, h, scene.settings.filter);
        gpu.render_into(&mut film, seed, 0, gspp, |_| {}).unwrap();
        let (t, c) = halves(&film);
        println!(
            "gpu seed {seed}: strip total {:.4} camera {:.4} splats {:.4}; image total {:.4} camera {:.4}",
            strip(&t, w, x0, x1, y0, y1),
            strip(&c, w, x0, x1, y0, y1),
            strip(&t, w, x0, x1, y0, y1) - strip(&c, w, x0, x1, y0, y1),
            strip(&t, w, 0, w, 0, h),
            strip(&c, w, 0, w, 0, h)
        );
        let mut pt = GpuRenderer::new(&scene, Estimator::Pt).unwrap();
        let mut pf = Film::new(w, h, scene.settings.filter);
        pt.render_into(&mut pf, seed, 0, gspp, |_| {}).unwrap();
        let p = pf.image();
        println!(
            "gpu pt seed {seed}: strip {:.5}; image {:.5}; ibpt camera half strip {:.5}",
            strip(&p, w, x0, x1, y0, y1),
            strip(&p, w, 0, w, 0, h),
            strip(&c, w, x0, x1, y0, y1)
        );
        let mut cpu = skelight::integrator::registry::create("ibpt", &[]).unwrap();
        let opts = RenderOptions { spp: Some(cspp), time: None, seed: seed + 100, threads: 0 };
        let film = render(&scene, cpu.as_mut(), &opts, None, |_, _| true).unwrap().film;
        let (t, c) = halves(&film);
        println!(
            "cpu seed {}: strip total {:.4} camera {:.4} splats {:.4}; image total {:.4} camera {:.4}",
            seed + 100,
            strip(&t, w, x0, x1, y0, y1),
            strip(&c, w, x0, x1, y0, y1),
            strip(&t, w, x0, x1, y0, y1) - strip(&c, w, x0, x1, y0, y1),
            strip(&t, w, 0, w, 0, h),
            strip(&c, w, 0, w, 0, h)
        );
    }
}
