// The bake's vector kernels: one set per instruction set, each giving the same bits. Every phase
// that has vector kernels (the probes' ray directions, classification, products and lit hits;
// the albedo lookup; the bounces' gather) keeps a table of them per set, and the set in use is
// chosen once, as Embree picks its ISA kernels once (kernels/bvh/bvh8_factory.cpp): the best this
// CPU runs, unless setKernels asks for another (tests compare the sets, benchmarks time them).
#pragma once

namespace prt::bake {

/// A set of kernels. Avx512: AVX-512 F, VL, DQ and BW, with what Avx2 needs; Avx2: AVX2, FMA and
/// F16C; Portable: plain C++ on any CPU. Auto: the best set this CPU runs.
enum class Kernels { Auto, Avx512, Avx2, Portable };

/// Chooses the set the bakes that start from now on use (Auto until called). A set this CPU
/// cannot run gives the best one it can (Avx512 on a CPU with AVX2 alone: Avx2). Call it between
/// bakes, not during one.
void setKernels(Kernels kernels);

/// The set in use: what setKernels asked for, as this CPU runs it (never Auto).
Kernels activeKernels();

/// The best set this CPU runs (never Auto).
Kernels bestKernels();

/// "auto", "avx512", "avx2" or "portable".
const char* kernelsName(Kernels kernels);

}  // namespace prt::bake
