"""Writes ur20.urdf from the Universal Robots UR20's published DH and dynamics table.

Source (facts, typed in here): Universal Robots, "DH Parameters for calculations of
kinematics and dynamics", support article,
https://universal-robots.com/articles/ur/application-installation/dh-parameters-for-calculations-of-kinematics-and-dynamics
(table "UR20": theta, a, d, alpha of joints 1-6; mass, centre of mass and inertia matrix
of links 0-5, the link moved by joint k+1, in the DH frame k+1).

Standard DH: frame k = frame k-1 * Rz(theta_k) Tz(d_k) Tx(a_k) Rx(alpha_k). The URDF link
`link_k` (k = 1..6) has the frame Rz(theta_k) after frame k-1, the frame that joint k
turns; joint k+1 sits at Tz(d_k) Tx(a_k) Rx(alpha_k) from it (xyz = (a_k, 0, d_k), rpy =
(alpha_k, 0, 0)), and the link's inertial frame is the DH frame k (origin moved by the
centre of mass c_k given in it; the inertia matrix in its axes, about the centre of mass).
The base link and the flange (DH frame 6) have no mass.

    /usr/bin/python3 examples/urdf_arm/make_ur20_urdf.py > examples/urdf_arm/ur20.urdf
"""
import math

a = [0, -0.8620, -0.7287, 0, 0, 0]
d = [0.2363, 0, 0, 0.2010, 0.1593, 0.1543]
alpha = [math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0]
mass = [16.343, 29.632, 7.879, 3.054, 3.126, 0.846]
com = [[0, -0.0610, 0.0062], [0.5226, 0, 0.2098], [0.3234, 0, 0.0604],
       [0, -0.0026, 0.0393], [0, 0.0024, 0.0379], [0, -0.0003, -0.0318]]
# Row by row, as published: [Ixx, Ixy, Ixz, Iyx, Iyy, Iyz, Izx, Izy, Izz].
inertia = [[0.0887, -0.0001, -0.0001, -0.0001, 0.0763, 0.0072, -0.0001, 0.0072, 0.0842],
           [0.1467, 0.0002, -0.0516, 0.0002, 4.6659, 0.0000, -0.0516, 0.0000, 4.6348],
           [0.0261, -0.0001, -0.0290, -0.0001, 0.7576, -0.0000, -0.0290, -0.0000, 0.7533],
           [0.0056, -0.0000, -0.0000, -0.0000, 0.0054, 0.0004, -0.0000, 0.0004, 0.0040],
           [0.0059, -0.0000, 0.0000, -0.0000, 0.0058, -0.0004, 0.0000, -0.0004, 0.0043],
           [0.0009, 0.0000, 0.0000, 0.0000, 0.0009, 0.0000, 0.0000, 0.0000, 0.0012]]
# Joint range +-2 pi (the UR joints turn +-360 degrees). The table gives no torque or speed
# limits; URDF's <limit> needs the attributes, so effort and velocity are 0 here (unknown).


def g(x):
    return repr(float(x))


def main():
    out = ['<?xml version="1.0"?>',
           '<!-- Universal Robots UR20 from its published DH and dynamics table; written by',
           '     make_ur20_urdf.py (see there for the source and the frame conventions). -->',
           '<robot name="ur20">',
           '  <link name="base_link"/>']
    for k in range(6):
        c = com[k]
        ca, sa = math.cos(alpha[k]), math.sin(alpha[k])
        # DH frame k's origin and the centre of mass in link_k's frame.
        cx = a[k] + c[0]
        cy = ca * c[1] - sa * c[2]
        cz = d[k] + sa * c[1] + ca * c[2]
        I = inertia[k]
        out += [f'  <link name="link_{k + 1}">',
                '    <inertial>',
                f'      <origin xyz="{g(cx)} {g(cy)} {g(cz)}" rpy="{g(alpha[k])} 0 0"/>',
                f'      <mass value="{g(mass[k])}"/>',
                f'      <inertia ixx="{g(I[0])}" ixy="{g(I[1])}" ixz="{g(I[2])}" iyy="{g(I[4])}" '
                f'iyz="{g(I[5])}" izz="{g(I[8])}"/>',
                '    </inertial>',
                '  </link>']
        parent = 'base_link' if k == 0 else f'link_{k}'
        if k == 0:
            origin = '<origin xyz="0 0 0" rpy="0 0 0"/>'
        else:
            origin = f'<origin xyz="{g(a[k - 1])} 0 {g(d[k - 1])}" rpy="{g(alpha[k - 1])} 0 0"/>'
        out += [f'  <joint name="joint_{k + 1}" type="revolute">',
                f'    <parent link="{parent}"/>',
                f'    <child link="link_{k + 1}"/>',
                f'    {origin}',
                '    <axis xyz="0 0 1"/>',
                f'    <limit lower="{g(-2 * math.pi)}" upper="{g(2 * math.pi)}" effort="0" velocity="0"/>',
                '  </joint>']
    out += ['  <link name="flange"/>',
            '  <joint name="flange_joint" type="fixed">',
            '    <parent link="link_6"/>',
            '    <child link="flange"/>',
            f'    <origin xyz="{g(a[5])} 0 {g(d[5])}" rpy="{g(alpha[5])} 0 0"/>',
            '  </joint>',
            '</robot>']
    print('\n'.join(out))


if __name__ == '__main__':
    main()
