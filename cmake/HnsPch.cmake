# Precompiled headers: the standard library, Eigen and oneTBB headers that most translation units include
# (and GoogleTest for the tests, nlohmann/json for the command line) are parsed once per target instead of
# once per file. Parsing headers was 27-45 % of a heavy file's compile time under ASan + UBSan (clang
# -ftime-trace of tests/nn/actor_critic_test.cpp, tests/batch/scenes_test.cpp, src/ppo/trainer.cpp), most of
# it in these libraries' headers, and CI builds the tree about three times.
#
# hns_precompile(target [header...]): a precompiled header for this target alone: the extra headers given,
#   then the common list (the libraries, the CLI and the Python module, whose files share their flags within
#   the target; pybind11 comes first, as Python.h must).
# hns_precompile_test(target): the tests' one shared precompiled header, built by hns_test_pch
#   (tests/CMakeLists.txt), whose flags every GoogleTest executable has.
#
# Each file still includes what it uses; a tree configured with -DHNS_PCH=OFF compiles every file on its
# own includes and shows one that relies on the precompiled header.
option(HNS_PCH "Precompile the headers most files include (faster clean builds)" ON)

set(HNS_PCH_HEADERS
  <algorithm> <array> <cmath> <cstdint> <cstdio> <cstring> <functional> <limits> <memory> <optional> <span>
  <sstream> <stdexcept> <string> <string_view> <vector>
  <Eigen/Core> <oneapi/tbb/parallel_for.h> <oneapi/tbb/task_arena.h>)

function(hns_precompile target)
  if(HNS_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN} ${HNS_PCH_HEADERS})
  endif()
endfunction()

function(hns_precompile_test target)
  if(HNS_PCH)
    target_precompile_headers(${target} REUSE_FROM hns_test_pch)
  endif()
endfunction()

# GCC falls back to the header's text, silently, where a precompiled header does not fit a file's flags;
# this says so (clang refuses such a file outright).
if(HNS_PCH AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  target_compile_options(hns_options INTERFACE -Winvalid-pch)
endif()
