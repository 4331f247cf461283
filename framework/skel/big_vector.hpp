#pragma once
// Vectors for large scratch buffers (queues, run lists): a fresh allocation of 8 MiB or more gets the
// transparent-huge-page advice before its first touch (one page fault per 2 MiB instead of per
// 4 KiB: a large part of filling a new buffer, worse in virtual machines), and resize() leaves new
// elements default-initialised (no zero pass over memory the caller fills anyway).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "skel/volume.hpp"

namespace skel {

template <class T>
struct BigBufferAllocator {
  using value_type = T;
  BigBufferAllocator() = default;
  template <class U>
  BigBufferAllocator(const BigBufferAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  T* allocate(std::size_t n) {
    T* p = std::allocator<T>{}.allocate(n);
    advise_huge_pages(p, n * sizeof(T));
    return p;
  }
  void deallocate(T* p, std::size_t n) noexcept { std::allocator<T>{}.deallocate(p, n); }
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const BigBufferAllocator<U>&) const noexcept {
    return true;
  }
};

template <class T>
using BigVector = std::vector<T, BigBufferAllocator<T>>;

// Makes room for at least n elements of a full BigVector without the peak of a plain reallocation:
// the elements move to a new buffer (twice the capacity, at least n) 2 MiB at a time, and the old
// buffer's pages go back to the kernel behind the copy, so the old and the new buffer are never
// both resident (a queue that grows to hundreds of MiB would otherwise need its size twice over at
// that moment). For trivially copyable elements.
template <class T>
void grow_releasing(BigVector<T>& v, size_t n) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (n <= v.capacity()) return;
  BigVector<T> nv;
  nv.reserve(std::max(n, 2 * v.capacity()));
  constexpr size_t kChunk = (size_t{2} << 20) / sizeof(T);
  char* const old = reinterpret_cast<char*>(v.data());
  uintptr_t from = reinterpret_cast<uintptr_t>(old);  // the old buffer's bytes before this are given back
  for (size_t i = 0; i < v.size(); i += kChunk) {
    const size_t e = std::min(v.size(), i + kChunk);
    nv.insert(nv.end(), v.data() + i, v.data() + e);
    const uintptr_t end = reinterpret_cast<uintptr_t>(old + e * sizeof(T));
    const size_t n_rel = release_pages(reinterpret_cast<void*>(from), end - from);
    if (n_rel > 0) from = ((from + 4095) & ~uintptr_t{4095}) + n_rel;
  }
  v.swap(nv);
}

}  // namespace skel
