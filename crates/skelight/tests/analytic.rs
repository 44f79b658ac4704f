//! Configurations with exact answers, rendered through the whole pipeline (XML loader,
//! BVH, materials, lights, estimator, film).

mod common;

use common::*;
use skelight::estimators::by_name;
use skelight::scene::load::load;

fn scene_file(name: &str, xml: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("skelight-analytic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, xml).unwrap();
    p
}

/// A scene of `shapes` under a uniform sky of radiance 1, seen from `origin` towards the
/// origin on a square film of `size` pixels.
fn under_the_sky(max_depth: i32, fov: f32, origin: &str, size: u32, shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
      <integrator type="path"><integer name="max_depth" value="{max_depth}"/></integrator>
      <sensor type="perspective"><float name="fov" value="{fov}"/>
        <transform name="to_world"><lookat origin="{origin}" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="{size}"/><integer name="height" value="{size}"/><rfilter type="box"/></film>
      </sensor>
      {shapes}
      <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    </scene>"#
    )
}

/// A diffuse (albedo 0.7) vertical face above an unbounded floor under a uniform sky of
/// radiance 1 receives sky light from exactly the upper half of its hemisphere: with
/// direct lighting only, it shows 0.7 · 1/2 = 0.35. (Mitsuba 3.9.1 renders ≈ 0.40 here.)
#[test]
fn vertical_face_under_sky_over_a_floor() {
    let xml = under_the_sky(
        2,
        10.0,
        "0, 0, 5",
        32,
        r#"<bsdf type="diffuse" id="w"><rgb name="reflectance" value="0.7"/></bsdf>
      <shape type="rectangle"><transform name="to_world"><scale value="10000"/><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="w"/></shape>
      <shape type="rectangle"><ref id="w"/></shape>"#,
    );
    let scene = load(&scene_file("face.xml", &xml), &[]).unwrap();
    let film = render_spp(&scene, by_name("pt").unwrap().as_mut(), 256, 3);
    let (m, se) = film_mean_se(&film);
    let (m, se) = (m[0], se[0]);
    // The floor seen past 10⁴ units below the horizon adds < 1e-4.
    assert!((m - 0.35).abs() < 5.0 * se + 1e-4, "vertical face: {m} ± {se}, expected 0.35");
}

/// Furnace: inside a closed box whose every wall emits Le and reflects ρ diffusely, the
/// radiance is Le/(1−ρ) everywhere (unbounded depth, Russian roulette included).
#[test]
fn closed_emitting_box_reaches_the_geometric_series() {
    let xml = r#"<scene version="3.0.0">
      <integrator type="path"><integer name="max_depth" value="-1"/><integer name="rr_depth" value="3"/></integrator>
      <sensor type="perspective"><float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0, 0, 0" target="0.3, 0.2, -1" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
      </sensor>
      <shape type="cube"><boolean name="flip_normals" value="true"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
    </scene>"#;
    let scene = load(&scene_file("box.xml", xml), &[]).unwrap();
    let film = render_spp(&scene, by_name("pt").unwrap().as_mut(), 128, 5);
    let (m, se) = film_mean_se(&film);
    let (m, se) = (m[0], se[0]);
    assert!((m - 2.0).abs() < 5.0 * se + 1e-3, "furnace box: {m} ± {se}, expected 2");
}

/// Mitsuba's `sphere` is traced as an exact sphere (one normal, no tessellation) unless it
/// is an ellipsoid, faceted on request, or an emitter (sampled on its triangles).
#[test]
fn spheres_are_exact_where_they_can_be() {
    let shape = |inner: &str| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
            <shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="0.5"/>{inner}</shape></scene>"#
        )
    };
    let exact = |inner: &str, file: &str| load(&scene_file(file, &shape(inner)), &[]).unwrap().meshes[0].sphere;
    let s = exact("", "plain.xml").expect("a plain sphere is exact");
    assert_eq!((s.center.x, s.center.y, s.center.z, s.radius), (1.0, 2.0, 3.0, 0.5));
    let rotated = r#"<transform name="to_world"><rotate y="1" angle="30"/><scale value="2"/></transform>"#;
    assert!((exact(rotated, "rotated.xml").unwrap().radius - 1.0).abs() < 1e-5);
    let squashed = r#"<transform name="to_world"><scale x="1" y="2" z="1"/></transform>"#;
    assert!(exact(squashed, "squashed.xml").is_none());
    assert!(exact(r#"<boolean name="face_normals" value="true"/>"#, "faceted.xml").is_none());
    assert!(exact(r#"<emitter type="area"><rgb name="radiance" value="1"/></emitter>"#, "lit.xml").is_none());
    assert!(exact(r#"<boolean name="flip_normals" value="true"/>"#, "flipped.xml").unwrap().inward);
}

/// A convex diffuse ball (albedo 0.7) under a uniform sky of radiance 1 sees the sky over
/// its whole upper hemisphere everywhere and never itself: it shows exactly 0.7. The view
/// holds only the ball, so the image mean is 0.7.
#[test]
fn diffuse_ball_under_the_sky_shows_its_albedo() {
    let xml = under_the_sky(
        4,
        8.0,
        "0.3, 0.2, 5",
        16,
        r#"<shape type="sphere"><float name="radius" value="1"/><bsdf type="diffuse"><rgb name="reflectance" value="0.7"/></bsdf></shape>"#,
    );
    let scene = load(&scene_file("ball.xml", &xml), &[]).unwrap();
    assert!(scene.meshes[0].sphere.is_some());
    let film = render_spp(&scene, by_name("pt").unwrap().as_mut(), 64, 5);
    let (m, se) = film_mean_se(&film);
    for c in 0..3 {
        assert!(se[c] > 0.0 && (m[c] - 0.7).abs() < 5.0 * se[c] + 1e-4, "{} ± {}, expected 0.7", m[c], se[c]);
    }
}

/// Under Mitsuba 3's `sunsky` (a 5° sun at 35° from the zenith), a diffuse floor shows
/// ρ/π · E, E the irradiance found by quadrature of the emitter's own radiance over the
/// hemisphere (sky) and over the sun's cap. Every estimator must find it: pt (NEE + BSDF
/// sampling), lt (rays from the sun and sky onto the floor), bpt and ibpt.
#[test]
fn floor_under_sunsky_shows_the_sky_and_sun_irradiance() {
    use skelight::light::Light;
    use skelight::math::{vec3, Frame};
    let xml = r#"<scene version="3.0.0">
      <integrator type="path"><integer name="max_depth" value="2"/></integrator>
      <sensor type="perspective"><float name="fov" value="20"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="48"/><rfilter type="box"/></film>
      </sensor>
      <shape type="rectangle"><transform name="to_world"><scale value="2"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf></shape>
      <emitter type="sunsky"><vector name="sun_direction" value="0.4, 0.3, 0.7"/><float name="turbidity" value="4"/>
        <float name="sun_aperture" value="5"/><float name="sun_scale" value="0.3"/></emitter>
    </scene>"#;
    let scene = load(&scene_file("sunsky.xml", xml), &[]).unwrap();
    let Some(Light::Env(sky)) = scene.lights.first() else { panic!("sunsky not loaded as an environment") };
    let sun = vec3(0.4, 0.3, 0.7).normalize();
    // Sky: midpoint rule in (cosθ, φ); the sun's cap is integrated separately below, so
    // points inside it are skipped here.
    let half = 2.5f64.to_radians();
    let (nc, np) = (1024, 1024);
    let mut e_sky = 0.0f64;
    for i in 0..nc {
        let ct = (i as f64 + 0.5) / nc as f64;
        let st = (1.0 - ct * ct).sqrt();
        for j in 0..np {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
            let d = vec3((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
            if (d.dot(sun) as f64) < half.cos() {
                e_sky += sky.eval(d).g as f64 * ct;
            }
        }
    }
    e_sky *= 2.0 * std::f64::consts::PI / (nc * np) as f64;
    // Sun's cap: polar grid around its centre.
    let frame = Frame::from_normal(sun);
    let (nr, na) = (400, 64);
    let mut e_sun = 0.0f64;
    for i in 0..nr {
        let a = half * (i as f64 + 0.5) / nr as f64;
        for j in 0..na {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / na as f64;
            let local = vec3((a.sin() * phi.cos()) as f32, (a.sin() * phi.sin()) as f32, a.cos() as f32);
            let d = frame.to_world(local);
            e_sun += sky.eval(d).g as f64 * d.z as f64 * a.sin();
        }
    }
    e_sun *= (half / nr as f64) * (2.0 * std::f64::consts::PI / na as f64);
    let expected = 0.6 / std::f64::consts::PI * (e_sky + e_sun);
    assert!(e_sun > 0.5 * e_sky, "the test should exercise the sun: sky {e_sky}, sun {e_sun}");
    for (name, spp) in every_estimator() {
        let spp = if name == "lt" { spp } else { 32 };
        let mut integrator = by_name(name).unwrap();
        let a = render_spp(&scene, integrator.as_mut(), spp, 11).image();
        let b = render_spp(&scene, integrator.as_mut(), spp, 12).image();
        let (m, se) = pair_mean_se(&a, &b);
        // Standard errors from 36 pairs of 8×8 blocks; the quadrature's own error (cap edge,
        // midpoint rule) is below 0.3 %.
        assert!(
            (m[1] - expected).abs() < 5.0 * se[1] + 3e-3 * expected,
            "{name}: floor {} ± {}, expected {expected} (sky {e_sky}, sun {e_sun})",
            m[1],
            se[1]
        );
    }
}
