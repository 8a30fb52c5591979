// The translation unit that builds the tests' precompiled header
// (tests/CMakeLists.txt, exodaq_test_pch); it holds no code of its own.
