# Finds hns's dependencies (all from Debian 12 packages) and fails with the package to install.
find_package(PkgConfig QUIET)

function(hns_missing what package)
  message(FATAL_ERROR "hns: ${what} not found. Install it with: apt-get install ${package} "
                      "(tools/run and tools/test install every missing package themselves).")
endfunction()

# ODE (double precision, Debian libode-dev). Linked as a shared library: hns interposes ODE's
# dRandInt with a per-world stream for determinism (see src/physics/ode_runtime.cpp).
if(NOT PkgConfig_FOUND)
  hns_missing("pkg-config" "pkg-config")
endif()
pkg_check_modules(ODE IMPORTED_TARGET ode)
if(NOT ODE_FOUND)
  hns_missing("ODE (Open Dynamics Engine)" "libode-dev")
endif()

# libgd (Debian libgd-dev): the top-down pictures and animated GIFs of recorded episodes (replay/render.hpp).
pkg_check_modules(GD IMPORTED_TARGET gdlib)
if(NOT GD_FOUND)
  hns_missing("libgd" "libgd-dev")
endif()

find_package(Eigen3 3.4 QUIET NO_MODULE)
if(NOT Eigen3_FOUND)
  hns_missing("Eigen 3.4" "libeigen3-dev")
endif()
find_package(xsimd QUIET)
if(NOT xsimd_FOUND)
  hns_missing("xsimd" "libxsimd-dev")
endif()
# Debian's xsimd 8 target names the optional xtl library as a link dependency although hns uses no xtl
# feature; drop it so nothing tries to link -lxtl.
set_target_properties(xsimd PROPERTIES INTERFACE_LINK_LIBRARIES "")
find_package(TBB QUIET COMPONENTS tbb)
if(NOT TBB_FOUND)
  hns_missing("oneTBB" "libtbb-dev")
endif()
find_package(CLI11 QUIET)
if(NOT CLI11_FOUND)
  hns_missing("CLI11" "libcli11-dev")
endif()
find_package(nlohmann_json 3 QUIET)
if(NOT nlohmann_json_FOUND)
  hns_missing("nlohmann-json" "nlohmann-json3-dev")
endif()
if(HNS_BUILD_TESTS)
  find_package(GTest QUIET)
  if(NOT GTest_FOUND)
    hns_missing("GoogleTest" "libgtest-dev")
  endif()
endif()
if(HNS_BUILD_BENCH)
  find_package(benchmark QUIET)
  if(NOT benchmark_FOUND)
    hns_missing("Google Benchmark" "libbenchmark-dev")
  endif()
endif()

# MPI for data-parallel training (the C API, from C++ without MPI's old C++ bindings; the command line alone
# links it).
if(HNS_MPI)
  set(MPI_CXX_SKIP_MPICXX ON)
  find_package(MPI QUIET COMPONENTS CXX)
  if(NOT MPI_CXX_FOUND)
    hns_missing("MPI (for hns train across processes; -DHNS_MPI=OFF builds without it)" "libopenmpi-dev")
  endif()
  find_program(HNS_MPIEXEC NAMES mpirun mpiexec)
  if(NOT HNS_MPIEXEC)
    hns_missing("mpirun (to launch and test hns train across processes)" "openmpi-bin")
  endif()
endif()
# Python module: Debian's python3 (the interpreter python3-numpy and python3-pytest install for; a pyenv or
# virtualenv python3 earlier on PATH usually lacks numpy), its headers, pybind11 and numpy.
if(HNS_PYTHON)
  if(NOT DEFINED Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python3_EXECUTABLE /usr/bin/python3)
  endif()
  find_package(Python3 COMPONENTS Interpreter Development.Module QUIET)
  if(NOT Python3_Development.Module_FOUND)
    hns_missing("Python 3 headers (for the Python module; -DHNS_PYTHON=OFF builds without it)" "python3-dev")
  endif()
  find_package(pybind11 2.6 CONFIG QUIET)
  if(NOT pybind11_FOUND)
    hns_missing("pybind11 (for the Python module; -DHNS_PYTHON=OFF builds without it)" "pybind11-dev")
  endif()
  execute_process(COMMAND ${Python3_EXECUTABLE} -c "import numpy" RESULT_VARIABLE HNS_NUMPY_MISSING
                  OUTPUT_QUIET ERROR_QUIET)
  if(HNS_NUMPY_MISSING)
    hns_missing("numpy for ${Python3_EXECUTABLE} (for the Python module; -DHNS_PYTHON=OFF builds without it)"
                "python3-numpy")
  endif()
endif()
