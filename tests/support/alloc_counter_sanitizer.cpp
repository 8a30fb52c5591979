// The allocation counter for sanitizer builds (EXODAQ_SANITIZE=address or
// thread). ASan and TSan bring their own malloc/free and operator new, so
// alloc_counter.cpp's replacements (which forward to glibc's __libc_malloc)
// would hand ASan-unknown memory to the sanitizer's free, or bypass it. Here
// nothing is replaced: the counter registers a malloc hook with the sanitizer
// runtime, which calls it for every allocation (malloc, calloc, realloc,
// posix_memalign, aligned_alloc and every operator new), so the
// zero-allocation tests count the same calls and keep running under the
// sanitizers.
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "alloc_counter.hpp"

extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));

namespace {
thread_local std::uint64_t t_allocations = 0;
std::atomic<std::uint64_t> g_allocations{0};

void on_malloc(const volatile void* /*p*/, std::size_t /*size*/) {
  ++t_allocations;
  g_allocations.fetch_add(1, std::memory_order_relaxed);
}

void on_free(const volatile void* /*p*/) {}

const int g_installed = __sanitizer_install_malloc_and_free_hooks(&on_malloc, &on_free);
}  // namespace

namespace exodaq::test {
std::uint64_t thread_allocations() noexcept {
  (void)g_installed;
  return t_allocations;
}
std::uint64_t process_allocations() noexcept {
  return g_allocations.load(std::memory_order_relaxed);
}
}  // namespace exodaq::test
