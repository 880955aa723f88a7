// Counts heap allocations made through operator new, so that a test can show that a
// computation makes none: compare g_allocations before and after it. Replaces the global
// operator new/delete of the program: include it in exactly one translation unit of a
// test executable.
#pragma once

#include <cstdlib>
#include <new>

static long g_allocations = 0;

void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
