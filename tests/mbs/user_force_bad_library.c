/* Deliberately broken user-force libraries for the error tests of mbs/user_force:
 * built with -DBAD_ABI_VERSION it reports a wrong ABI version; without it, it does not
 * export mbdae_user_force_abi_version at all. */
#include "api/mbdae_user_force.h"

#ifdef BAD_ABI_VERSION
__attribute__((visibility("default"))) int mbdae_user_force_abi_version(void) {
  return MBDAE_USER_FORCE_ABI_VERSION + 998;
}
#endif

__attribute__((visibility("default"))) int some_force(const mbdae_user_force_input* in,
                                                     mbdae_user_force_output* out) {
  (void)in;
  (void)out;
  return 0;
}
