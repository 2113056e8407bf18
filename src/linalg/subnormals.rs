//! Subnormal numbers flushed to zero while a kernel runs.
//!
//! On x86 an operation with a subnormal operand or result takes a microcode assist, about a
//! hundred times a normal one. faer's Euclidean norm (used for every Householder vector and
//! for the renormalisation of C) keeps three accumulators so that it cannot overflow or
//! underflow, one of them of (x sqrt(2.2e-308))^2: for every |x| < 1 that term is subnormal,
//! and it is discarded unless the norm is above 1e154. Flushing such terms to zero cannot
//! change a norm below that, and our tangent blocks hold no subnormal number themselves:
//! on the disks' D = 792 tangent block, faer's factorisation took 13.2 ms instead of 18.6
//! ms on one core, and normalising the columns of C 0.66 ms instead of 2.7 ms, with the same
//! bits (examples/qr_realistic.rs). A result changes only where a true subnormal, below
//! 2.2e-308, would have entered it.

/// Sets flush-to-zero and denormals-are-zero on this thread until dropped, then restores
/// the thread's previous mode. A no-op on other architectures than x86-64 and aarch64.
pub struct FlushSubnormals {
    #[allow(dead_code)]
    saved: u64,
}

impl FlushSubnormals {
    #[cfg(target_arch = "x86_64")]
    pub fn new() -> Self {
        const FTZ_DAZ: u32 = 0x8040;
        let mut csr: u32 = 0;
        // Safety: stmxcsr/ldmxcsr only read and write the SSE control register of this
        // thread; FTZ and DAZ are valid bits of it on every x86-64 CPU with SSE3 (all).
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
            let set = csr | FTZ_DAZ;
            std::arch::asm!("ldmxcsr [{}]", in(reg) &set, options(nostack));
        }
        FlushSubnormals { saved: csr as u64 }
    }

    #[cfg(target_arch = "aarch64")]
    pub fn new() -> Self {
        const FZ: u64 = 1 << 24;
        let fpcr: u64;
        // Safety: reads and writes this thread's floating-point control register only.
        unsafe {
            std::arch::asm!("mrs {}, fpcr", out(reg) fpcr, options(nomem, nostack));
            std::arch::asm!("msr fpcr, {}", in(reg) fpcr | FZ, options(nomem, nostack));
        }
        FlushSubnormals { saved: fpcr }
    }

    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    pub fn new() -> Self {
        FlushSubnormals { saved: 0 }
    }
}

impl Default for FlushSubnormals {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for FlushSubnormals {
    fn drop(&mut self) {
        #[cfg(target_arch = "x86_64")]
        {
            let csr = self.saved as u32;
            // Safety: restores the value read in `new`.
            unsafe { std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack)) };
        }
        #[cfg(target_arch = "aarch64")]
        // Safety: restores the value read in `new`.
        unsafe {
            std::arch::asm!("msr fpcr, {}", in(reg) self.saved, options(nomem, nostack))
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny_product() -> f64 {
        let x = std::hint::black_box(1e-160_f64);
        std::hint::black_box(x * x * 1e100)
    }

    #[test]
    fn flushes_while_held_and_restores_after() {
        let before = tiny_product();
        assert!(before > 0.0, "1e-320 * 1e100 as computed with gradual underflow");
        {
            let _flush = FlushSubnormals::new();
            #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
            assert_eq!(tiny_product(), 0.0);
            // Subnormal inputs read as zero too (DAZ on x86): 5e-324 * 1e300 would be 5e-24.
            #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
            assert_eq!(std::hint::black_box(f64::from_bits(1)) * std::hint::black_box(1e300), 0.0);
            {
                let _nested = FlushSubnormals::new();
            }
            #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
            assert_eq!(tiny_product(), 0.0, "a nested guard restores the flushing mode");
        }
        assert_eq!(tiny_product().to_bits(), before.to_bits());
    }
}
