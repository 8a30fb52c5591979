# Sourced by scripts/build, scripts/sanitize and scripts/fuzz: ccache (when
# installed) as the compiler launcher, so rebuilds, several checkouts of the
# tree and CI's sanitizer and fuzz builds stay cheap (issue 17: the CI
# budget). CCACHE_BASEDIR makes its keys independent of where the tree lives.
# Sets CCACHE_LAUNCHER: the cmake arguments (none without ccache).
CCACHE_LAUNCHER=()
if command -v ccache >/dev/null; then
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
  # The four builds (plain, ASan, TSan, fuzz) hold about 6 GB of objects:
  # ccache's default 5 GB evicted the ASan build's between CI runs (977 s to
  # rebuild it cold, the largest part of CI's time).
  export CCACHE_MAXSIZE="${CCACHE_MAXSIZE:-16G}"
  # The tests' and the exodaq tool's precompiled headers (tests/CMakeLists.txt):
  # what ccache needs to cache a compile that uses one.
  export CCACHE_SLOPPINESS="pch_defines,time_macros,include_file_mtime,include_file_ctime"
  CCACHE_LAUNCHER=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
