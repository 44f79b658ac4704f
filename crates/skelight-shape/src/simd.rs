//! Loops over bytes and 32-bit values compiled for AVX2 where the CPU has it. The release
//! build targets every x86-64, that is SSE2, where a vectorised loop does half the values a
//! step that AVX2 does, and u32 minima and maxima take three operations instead of one (door,
//! one thread: the complex's state bytes 5.7 -> 4.5 ms, the chessboard map 8.8 -> 6.5, W's
//! scan of the dates 21.6 -> 19.0).

/// Defines a function that calls a kernel (a function marked `#[inline(always)]`, with the
/// same arguments) compiled for AVX2 where the CPU has it, and as it is elsewhere. The
/// kernel is inlined into both versions, so its loops are compiled twice. (A closure handed
/// to a function compiled for AVX2 stays compiled without it, so the kernel must be a
/// function.)
macro_rules! avx2_dispatch {
    ($(#[$doc:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? => $kernel:ident) => {
        $(#[$doc])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $kernel($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $kernel($($arg),*)
        }
    };
}
pub(crate) use avx2_dispatch;

avx2_dispatch! {
    /// Each value of `to` lowered to its value in `from` plus one: a step of the L1 map's
    /// sweeps from a row to the next.
    pub(crate) fn lower_to_next(to: &mut [u32], from: &[u32]) => lower_to_next_kernel
}

avx2_dispatch! {
    /// Each value of `to` raised to its value in `from`.
    pub(crate) fn raise_to(to: &mut [u32], from: &[u32]) => raise_to_kernel
}

#[inline(always)]
fn lower_to_next_kernel(to: &mut [u32], from: &[u32]) {
    elementwise(to, from, |t, f| t.min(f + 1));
}

#[inline(always)]
fn raise_to_kernel(to: &mut [u32], from: &[u32]) {
    elementwise(to, from, u32::max);
}

/// `to[i] ← op(to[i], from[i])`.
#[inline(always)]
fn elementwise(to: &mut [u32], from: &[u32], op: impl Fn(u32, u32) -> u32) {
    for (t, &f) in to.iter_mut().zip(from) {
        *t = op(*t, f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dispatched versions (AVX2 on a CPU that has it) and the kernels as the build
    /// compiles them agree, on lengths around a vector's and values near u32's ends.
    #[test]
    fn both_versions_agree() {
        let mut r = crate::testing::Lcg(5);
        for n in [0, 1, 7, 8, 9, 31, 33, 200] {
            let mut value = || match r.next() {
                p if p < 0.1 => u32::MAX - 1,
                p => (p * 1000.0) as u32,
            };
            let (a, b): (Vec<u32>, Vec<u32>) = (0..n).map(|_| (value(), value())).unzip();
            for (dispatched, kernel) in [
                (lower_to_next as fn(&mut [u32], &[u32]), lower_to_next_kernel as fn(&mut [u32], &[u32])),
                (raise_to, raise_to_kernel),
            ] {
                let (mut x, mut y) = (a.clone(), a.clone());
                dispatched(&mut x, &b);
                kernel(&mut y, &b);
                assert_eq!(x, y, "length {n}");
            }
        }
    }
}
