// The translation unit of dcl_pch, the target whose precompiled header the
// libraries reuse (cmake/DclTargets.cmake): nothing of its own.
