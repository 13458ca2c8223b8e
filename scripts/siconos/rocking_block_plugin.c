/* Gaps of the two bottom corners of the rocking block and their Jacobians, as a Siconos
 * plugin for LagrangianScleronomousR (scripts/siconos/rocking_block.py compiles it). */
#include <math.h>
static const double W = 0.2, HGT = 0.4;
void h1(unsigned int sizeQ, double* q, unsigned int sizeY, double* y, unsigned int sizeZ, double* z)
{ y[0] = q[0] + 0.5*W*sin(q[1]) - 0.5*HGT*cos(q[1]); }
void G1(unsigned int sizeQ, double* q, unsigned int sizeY, double* jac, unsigned int sizeZ, double* z)
{ jac[0] = 1.0; jac[1] = 0.5*W*cos(q[1]) + 0.5*HGT*sin(q[1]); }
void h2(unsigned int sizeQ, double* q, unsigned int sizeY, double* y, unsigned int sizeZ, double* z)
{ y[0] = q[0] - 0.5*W*sin(q[1]) - 0.5*HGT*cos(q[1]); }
void G2(unsigned int sizeQ, double* q, unsigned int sizeY, double* jac, unsigned int sizeZ, double* z)
{ jac[0] = 1.0; jac[1] = -0.5*W*cos(q[1]) + 0.5*HGT*sin(q[1]); }
