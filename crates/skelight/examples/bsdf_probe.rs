use skelight::material::microfacet::*;
use skelight::material::*;
use skelight::math::*;
use skelight::texture::Texture;
fn main() {
    let mf = Microfacet::new(MicrofacetType::Ggx, 0.15, 0.15);
    let eta = 1.49 / 1.000277;
    let ctx = BsdfCtx { uv: vec2(0.3, 0.6), mode: TransportMode::Radiance };
    for nl in [false, true] {
        let b = Bsdf::RoughPlastic(RoughPlastic::new(mf, Texture::constant(0.5), Texture::constant(0.0), eta, nl));
        let mut out = vec![];
        for th in [0.0f32, 20.0, 40.0, 60.0, 70.0, 80.0, 85.0] {
            let t = th.to_radians();
            let wo = vec3(t.sin() * 0.7, -t.sin() * 0.714, t.cos());
            let v = b.eval(&ctx, vec3(0.0, 0.0, 1.0), wo).r;
            out.push(format!("{:.5}", v / (0.5 * INV_PI / (eta * eta) * t.cos())));
        }
        println!("nonlinear {nl} {out:?}");
    }
}
