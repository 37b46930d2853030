// The translation unit of hns_test_pch (tests/CMakeLists.txt): the target exists to build the precompiled
// header every GoogleTest executable of the suite reuses; it has no tests of its own.
