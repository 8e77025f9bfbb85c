/// @file
/// Vectors whose new elements are left uninitialized (default-initialized), for large arrays that
/// are filled right away, often in parallel: std::vector::resize would first zero them in one
/// thread, a pass over memory the filling pass then repeats.
#pragma once

#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace distile {

/// std::allocator, except that value-initialization (what resize asks for) default-initializes:
/// trivially constructible elements keep whatever the memory holds.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = DefaultInitAllocator<U>;
    };
    DefaultInitAllocator() noexcept = default;
    template <class U>
    DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}

    template <class U>
    void construct(U* place) noexcept(std::is_nothrow_default_constructible_v<U>) {
        ::new (static_cast<void*>(place)) U;
    }
    template <class U, class... Args>
    void construct(U* place, Args&&... args) {
        ::new (static_cast<void*>(place)) U(std::forward<Args>(args)...);
    }
};

/// A vector whose resize leaves new trivially constructible elements uninitialized.
template <class T>
using UninitializedVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace distile
