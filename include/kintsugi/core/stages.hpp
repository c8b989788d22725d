// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file stages.hpp
/// @brief Optional, for programs with many translation units: separate compilation of
/// the library's largest non-template functions (the stages of a method, e.g. the
/// PU + graph-cut run, the RBF octree fit, the example-based completion).
///
/// By default (header-only use) each stage is an `inline` function defined in its
/// header, through a `.ipp` file under `detail/` that the header includes. A program
/// that defines KINTSUGI_SEPARATE_STAGES in every translation unit (e.g. on the
/// compiler's command line) sees declarations only, and compiles each stage once, in a
/// file of its own that includes the stage's `.ipp` after its header:
///
/// @code
/// // stages_rbf.cpp, compiled with -DKINTSUGI_SEPARATE_STAGES like the rest of the program
/// #include <kintsugi/rbf/rbf_octree.hpp>
/// #include <kintsugi/rbf/detail/rbf_octree_fit.ipp>
/// @endcode
///
/// The code is the same, compiled with the same flags: results are identical. The
/// stages are compiled in parallel and once per program, not in every file that calls
/// them (docs/build.md: the `kintsugi` tool and the test programs do this).

/// `inline` in header-only use; nothing (one definition in the program) with
/// KINTSUGI_SEPARATE_STAGES.
#ifdef KINTSUGI_SEPARATE_STAGES
#define KINTSUGI_STAGE
#else
#define KINTSUGI_STAGE inline
#endif
