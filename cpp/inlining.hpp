// CS_ALWAYS_INLINE: small functions of the inner loops (box_in_frame, the edge-axis test ...)
// that the compiler's own inlining budget would leave out of line, where the call costs as
// much as the function.
#pragma once

#if defined(__GNUC__) || defined(__clang__)
#define CS_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define CS_ALWAYS_INLINE inline
#endif
