//! Run-time choice of the instruction set of the element-wise kernels.
//!
//! The release build targets baseline x86-64 (SSE2), so that one wheel runs on every x86-64
//! machine. [`multiversion!`](crate::multiversion) defines a kernel twice from one body: as
//! written, and inside a function compiled for AVX2 (where closures of the body inherit the
//! feature and are inlined), chosen at run time when the CPU has AVX2
//! (`is_x86_feature_detected!`, a cached flag). The compiler vectorises the AVX2 copy for
//! 256-bit registers. No FMA is enabled and the compiler neither contracts a·b + c nor
//! reorders floating-point operations, so both copies perform the same operations in the same
//! order and give the same bits.

/// Whether the AVX2 copies of the kernels run on this CPU.
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `multiversion! { fn name / name_base(args) -> T { body } }` defines `name`, which runs `body`
/// compiled for AVX2 when [`has_avx2`], else `name_base`, the same body compiled for the build's
/// target (also callable directly: the tests compare the two copies bit for bit).
#[macro_export]
#[doc(hidden)]
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis unsafe fn $name:ident / $base:ident ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        #[inline]
        #[allow(clippy::too_many_arguments)]
        $vis unsafe fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx2($($arg: $ty),*) $(-> $ret)? $body
                if $crate::operators::simd::has_avx2() {
                    // SAFETY: the CPU supports AVX2 (checked just above); the caller upholds the
                    // kernel's own contract.
                    return unsafe { avx2($($arg),*) };
                }
            }
            unsafe { $base($($arg),*) }
        }

        /// The baseline (build target) copy of the kernel of the same name without `_base`.
        ///
        /// # Safety
        /// As for the kernel of the same name.
        #[inline(always)]
        #[allow(clippy::too_many_arguments)]
        $vis unsafe fn $base($($arg: $ty),*) $(-> $ret)? $body
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident / $base:ident ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        #[inline]
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                #[allow(clippy::too_many_arguments)]
                fn avx2($($arg: $ty),*) $(-> $ret)? $body
                if $crate::operators::simd::has_avx2() {
                    // SAFETY: the CPU supports AVX2 (checked just above).
                    return unsafe { avx2($($arg),*) };
                }
            }
            $base($($arg),*)
        }

        /// The baseline (build target) copy of the kernel of the same name without `_base`.
        #[inline(always)]
        #[allow(clippy::too_many_arguments)]
        $vis fn $base($($arg: $ty),*) $(-> $ret)? $body
    };
}
