/* vh_tc.h - torque converter characteristic (lock-up open), shared by the ECU's input model and
 * the simulated plant: the ECU computes T_i from measured speeds with the same steady-state
 * characteristic the converter has (seed 001 sec. 2.3), as the paper does.
 *
 * Drive range r = w_t/w_e <= VH_TC_RC: eq. 9 exactly. Eq. 9's capacity fit is still 0.48e-3 at
 * r = 1 and crosses zero only at r ~ 1.13, so a converter following it as printed would push
 * the car at coupling. Between VH_TC_RC and 1 a quadratic blend, matching eq. 9's value and
 * slope at VH_TC_RC, takes the capacity to zero at r = 1; beyond, overrun torque grows
 * linearly with the slip at the blend's slope (the stator freewheels: T_i = T_p).
 */
#ifndef VH_TC_H
#define VH_TC_H

#define VH_TC_RC 0.9

/* Pump torque *tp and turbine torque *ti [Nm] at pump (engine) speed we and turbine speed wt
 * [rad/s]. we is floored at 1e-3 rad/s; r < 0 is taken as stall (r = 0). */
void vh_tc_torques(double we, double wt, double *tp, double *ti);
/* Steepest slope of the capacity, -dC/dr at coupling [Nm s^2/rad^2] (integrator step sizing). */
double vh_tc_max_slope(void);

#endif /* VH_TC_H */
