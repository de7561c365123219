from setuptools import find_packages, setup

package_name = "ft_core"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["urdf/*.urdf"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs test/ with pytest
    zip_safe=False,
    maintainer="ft-arms maintainers",
    maintainer_email="maintainers@ft-arms.org",
    description="ROS-free mathematics of the fault-tolerance suite.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "bounds = ft_core.offline.bounds:main",
            "design = ft_core.offline.design:main",
            "map = ft_core.offline.placement:main",
            "plan = ft_core.offline.planning:main",
            "swing = ft_core.offline.swing_workspace:main",
        ],
    },
)
