# Precompiled headers: the standard-library headers that most translation units include, and Eigen, oneTBB,
# GoogleTest, nlohmann/json or pybind11 where a target's files use them, are parsed once per target instead
# of once per file. Parsing headers was 27-45 % of a heavy file's compile time under ASan + UBSan (clang
# -ftime-trace of tests/nn/actor_critic_test.cpp, tests/batch/scenes_test.cpp, src/ppo/trainer.cpp), most of
# it in these libraries' headers, and CI builds the tree about three times.
#
# hns_precompile(target [header...]): a precompiled header for this target alone: the extra headers given,
#   then the standard-library list. The extra headers come first, so pybind11, which includes Python.h before
#   anything else, precedes the standard library. Every file of the target uses it; a file with flags of its
#   own must set SKIP_PRECOMPILE_HEADERS (as src/nn/isa_check.cpp does).
# hns_precompile_test(target): the GoogleTest executables' one shared precompiled header, built by
#   hns_test_pch (tests/CMakeLists.txt). A target that reuses it needs the same compile options as that
#   target (hns_options, an executable's -fPIE where the tree is position-independent, GoogleTest's
#   definitions); other include folders and unrelated -D definitions are fine.
#
# CMake compiles every such file with -Winvalid-pch, so a precompiled header that does not fit is reported.
# It changes no arithmetic, but it does change where the compiler places shared functions: the binaries'
# layout differs with HNS_PCH and with the lists below, and tools/perf-gate builds its baseline with the
# current tree's HNS_PCH. Each file still includes what it uses; CI's AVX2 tree (.ci/run) is configured
# with -DHNS_PCH=OFF and fails on a file of the physics, batch, nn or ppo libraries or of the network and
# trainer tests that relies on the precompiled header.
option(HNS_PCH "Precompile the headers most files include (faster clean builds)" ON)

set(HNS_PCH_STD
  <algorithm> <array> <cmath> <cstdint> <cstdio> <cstring> <functional> <limits> <memory> <optional> <span>
  <sstream> <stdexcept> <string> <string_view> <vector>)
set(HNS_PCH_TBB <oneapi/tbb/parallel_for.h> <oneapi/tbb/task_arena.h>)

function(hns_precompile target)
  if(HNS_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN} ${HNS_PCH_STD})
  endif()
endfunction()

function(hns_precompile_test target)
  if(HNS_PCH)
    target_precompile_headers(${target} REUSE_FROM hns_test_pch)
  endif()
endfunction()
