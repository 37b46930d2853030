# The documented install route: `cmake --install BUILD --component python --prefix P`, then `import hns` from
# P's dist-packages (and not from the build tree). Run by ctest as python_install_test.
set(prefix ${BUILD}/python-install-test)
file(REMOVE_RECURSE ${prefix})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD} --component python --prefix ${prefix}
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install --component python failed (${rc})")
endif()
file(GLOB site ${prefix}/lib/python*/dist-packages)
if(NOT site)
  message(FATAL_ERROR "nothing installed under ${prefix}/lib/python*/dist-packages")
endif()
execute_process(
  COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} ${PYTHON} -c
          "import hns, numpy as np; assert hns.__file__.startswith('${site}'), hns.__file__; env = hns.BatchEnv(num_envs=2, threads=1); a = np.zeros((2, env.max_agents, 5), np.uint8); a[..., :3] = 5; env.step(a); print('installed hns', hns.__version__, 'imported from ${site}')"

  WORKING_DIRECTORY ${prefix}
  RESULT_VARIABLE rc)
file(REMOVE_RECURSE ${prefix})
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "import hns from the installed package failed (${rc})")
endif()
